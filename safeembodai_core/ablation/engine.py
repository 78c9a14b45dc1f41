"""Run an ablation: pending trials -> executor -> results recorded as they finish -> resumable.

The scenario's state store records every step and every trial result (by default ``sqlite``
in ``<run>/results.sqlite``, written by the workers themselves as trials finish). A trial counts as
done only once its result is in the store, so after Ctrl-C, ``kill -9`` or a crashed worker a
resumed run re-runs exactly the missing trials: a trial cut off mid-way starts again from scratch
(``begin_trial`` drops its partial steps), none runs twice to completion.
"""

from __future__ import annotations

from typing import Callable


from ..errors import SafeEmbodAIError
from ..models import Outcome, TrialResult, TrialSpec
from ..plugins import Plugins
from ..runner import ScenarioRunner
from ..scenario import Scenario
from .executors import ProcessExecutor, RayExecutor, SerialExecutor
from .run_folder import RunFolder, RunLock

from ..logs import get_logger

log = get_logger(__name__)


class AblationError(SafeEmbodAIError):
    """The ablation cannot start or continue (the message says how to resume)."""


class Ablation:
    """One ablation run of ``scenario`` in ``folder``."""

    def __init__(self, scenario: Scenario, plugins: Plugins, folder: RunFolder, *, resume: bool = False,
                 workers: int = 1, executor: str | None = None, address: str | None = None) -> None:
        if workers < 1:
            raise AblationError("--workers must be at least 1")
        self.scenario, self.plugins, self.folder = scenario, plugins, folder
        self.workers, self.address = workers, address
        self.executor_name = executor or ("process" if workers > 1 else "serial")
        if self.executor_name not in ("serial", "process", "ray"):
            raise AblationError(f"unknown executor {self.executor_name!r}; choose serial, process or ray")
        if resume:
            folder.check_same(scenario)
        else:
            folder.start(scenario)
        self.lock = RunLock(folder.path)
        self.lock.acquire()
        self.runner = ScenarioRunner(scenario, plugins, run_dir=folder.path, save_trajectories=True)
        try:
            self.store = self.runner.state
            if resume and not self.store.persistent:
                raise AblationError(f"state store {scenario.state.use!r} keeps no results across runs: "
                                    "resuming needs a persistent store such as sqlite")
        except BaseException:
            self.close()
            raise
        self.resumed = resume

    def recorded(self) -> list[TrialResult]:
        """Results already in the store (empty for a store that does not keep them)."""
        try:
            return self.store.results()
        except NotImplementedError:
            return []

    def pending(self) -> list[TrialSpec]:
        """Trials without a result, and trials that ended in ``error`` (a backend outage is retried)."""
        done = {r.spec.trial_id for r in self.recorded() if r.outcome != Outcome.ERROR}
        return [spec for spec in self.runner.specs() if spec.trial_id not in done]

    def _executor(self):
        scenario_json = self.scenario.model_dump(mode="json")
        if self.executor_name == "serial":
            return SerialExecutor(self.runner)
        if not self.store.persistent:
            raise AblationError(f"--workers/--executor {self.executor_name} needs a persistent state store "
                                f"(e.g. sqlite); the scenario uses {self.scenario.state.use!r}")
        inline = sorted(name for name, origin in self.plugins.origins.items() if origin.source == "inline")
        if inline:
            raise AblationError(f"inline plugins ({', '.join(inline)}) cannot reach worker processes; "
                                "install them as packages or use the serial executor")
        if self.executor_name == "process":
            return ProcessExecutor(scenario_json, str(self.folder.path), self.workers)
        return RayExecutor(scenario_json, str(self.folder.path), self.workers, self.address)

    def run(self, on_result: Callable[[TrialResult], None] | None = None) -> list[TrialResult]:
        """Run every pending trial; return all results of the run (earlier ones included)."""
        pending = self.pending()
        log.info("ablation.start", run=str(self.folder.path), pending=len(pending), executor=self.executor_name)
        fresh: list[TrialResult] = []
        executor = self._executor()
        try:
            for result in executor.run(pending):
                if self.executor_name != "serial":
                    self.store.end_trial(result)  # idempotent: the worker's store already wrote it
                fresh.append(result)
                if on_result is not None:
                    on_result(result)
        finally:
            executor.close()
        return self.results(fresh)

    def results(self, fresh: list[TrialResult] | None = None) -> list[TrialResult]:
        by_id = {r.spec.trial_id: r for r in self.recorded()}
        for result in fresh or []:
            by_id[result.spec.trial_id] = result
        return self.runner.in_trial_order(list(by_id.values()))

    def close(self) -> None:
        try:
            self.runner.close()
        finally:
            self.lock.release()
