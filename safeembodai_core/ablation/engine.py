"""Run an ablation: pending trials -> executor -> results recorded as they finish -> resumable.

The scenario's state store records every step and every trial result (by default ``sqlite``,
one file in the run folder, written by the workers themselves as trials finish). A trial counts as
done only once its result is in the store, so after Ctrl-C, SIGTERM, ``kill -9`` or a crashed
worker a resumed run re-runs exactly the missing trials: a trial cut off mid-way starts again from
scratch (``begin_trial`` drops its partial steps), none runs twice to completion.

The store must not change under the run: the coordinator notes every finished trial in the run
folder's ledger (after the store has it) and checks, as results arrive and at the end, that the
store file is still the one it opened and still holds every trial of the ledger. A resume
refuses a store that lost trials of the ledger instead of quietly running them again.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path
from typing import Any, Callable


from ..errors import SafeEmbodAIError, StateStoreError
from ..models import Outcome, TrialResult, TrialSpec
from ..plugins import Plugins
from ..runner import ScenarioRunner
from ..scenario import Scenario
from .error_kinds import store_failed
from .executors import ProcessExecutor, SerialExecutor
from .run_folder import RunFolder, RunLock

from ..logs import get_logger

log = get_logger(__name__)

FULL_CHECK_EVERY_S = 2.0  # reading every result back costs O(trials): not after each trial of a fast run


class AblationError(SafeEmbodAIError):
    """The ablation cannot start or continue (the message says how to resume)."""


EXECUTORS = ("serial", "process", "ray")


def _not_persistent(executor: str, scenario: Scenario) -> AblationError:
    return AblationError(f"--workers/--concurrency/--executor {executor} needs a persistent state store "
                         f"(e.g. sqlite); the scenario uses {scenario.state.use!r}")


def _store_is_persistent(scenario: Scenario, plugins: Plugins) -> bool:
    """Whether the scenario's store keeps records across processes, asked of a store built in a
    scratch folder (so nothing appears in the run folder, which does not exist yet)."""
    with tempfile.TemporaryDirectory(prefix="safeembodai-store-check-") as scratch:
        runner = ScenarioRunner(scenario, plugins, run_dir=scratch)
        try:
            return bool(runner.state.persistent)
        finally:
            runner.close()


def executor_name(workers: int = 1, executor: str | None = None, address: str | None = None,
                  concurrency: int = 1) -> str:
    """The executor the options choose; options it would ignore are refused in one line.

    Trials run at once in threads (``concurrency`` > 1) run in worker processes, even with one
    worker: pybullet's chatter is silenced through the process-wide descriptors 1 and 2, which the
    coordinator's progress display and logs need."""
    if workers < 1:
        raise AblationError("--workers must be at least 1")
    if concurrency < 1:
        raise AblationError("--concurrency must be at least 1")
    name = executor or ("process" if workers > 1 or concurrency > 1 else "serial")
    if name not in EXECUTORS:
        raise AblationError(f"unknown executor {name!r}; choose serial, process or ray")
    if name == "serial" and (workers > 1 or concurrency > 1):
        option = f"--workers {workers}" if workers > 1 else f"--concurrency {concurrency}"
        raise AblationError(f"--executor serial runs one trial at a time, not {option}: "
                            f"drop {option.split()[0]}, or use --executor process or ray")
    if address is not None and name != "ray":
        raise AblationError(f"--address is the address of a Ray cluster: use it with --executor ray "
                            f"(the {name} executor would ignore it)")
    return name


def check_executor(scenario: Scenario, plugins: Plugins, *, workers: int = 1, executor: str | None = None,
                   address: str | None = None, concurrency: int = 1) -> str:
    """:func:`executor_name`, and that its workers can run the scenario: no inline plugins, a
    persistent store. Called before the run folder is made, so a refused run leaves nothing behind."""
    name = executor_name(workers, executor, address, concurrency)
    if name == "serial":
        return name
    inline = sorted(n for n, origin in plugins.origins.items() if origin.source == "inline")
    if inline:
        raise AblationError(f"inline plugins ({', '.join(inline)}) cannot reach worker processes; "
                            "install them as packages or use the serial executor")
    if not _store_is_persistent(scenario, plugins):
        raise _not_persistent(name, scenario)
    return name


class Ablation:
    """One ablation run of ``scenario`` in ``folder``."""

    def __init__(self, scenario: Scenario, plugins: Plugins, folder: RunFolder, *, resume: bool = False,
                 workers: int = 1, executor: str | None = None, address: str | None = None,
                 bags: str | None = None, concurrency: int = 1, cache: Any = None,
                 connect_timeout_s: float | None = None) -> None:
        self.scenario, self.plugins, self.folder = scenario, plugins, folder
        self.workers, self.address, self.concurrency = workers, address, concurrency
        self.connect_timeout_s = connect_timeout_s
        self.executor_name = check_executor(scenario, plugins, workers=workers, executor=executor, address=address,
                                            concurrency=concurrency)
        if resume:
            folder.check_same(scenario)
        else:
            folder.start(scenario)
        self.lock = RunLock(folder.path)
        self.lock.acquire()
        if bags is not None:
            folder.record_bags(bags)  # before any runner: every worker's reads it from the folder
        if cache is not None:  # a CacheSettings (what the run recorded on a resume without cache options)
            cache.write(folder.path)
        self.runner = ScenarioRunner(scenario, plugins, run_dir=folder.path, save_trajectories=True)
        try:
            pictures = folder.path / "trajectories"
            if pictures.exists() and not pictures.is_dir():
                raise AblationError(f"{pictures} is not a folder; move it away so the run can save its pictures there")
            self.store = self.runner.state
            if resume and not self.store.persistent:
                raise AblationError(f"state store {scenario.state.use!r} keeps no results across runs: "
                                    "resuming needs a persistent store such as sqlite")
            store_path = getattr(self.store, "path", None)  # a store kept in a file says where
            self.store_file = Path(store_path) if isinstance(store_path, (str, Path)) else None
            self.store_identity = self._identity()
            self.ledger = self._check_ledger() if resume else set()
        except BaseException:
            self.close()
            raise
        self.resumed = resume
        self._checked_at = time.monotonic()

    def _store_name(self) -> str:
        return str(self.store_file) if self.store_file else f"state store {self.scenario.state.use!r}"

    def _identity(self) -> tuple[int, int] | None:
        if self.store_file is None:
            return None
        try:
            info = os.stat(self.store_file)
        except FileNotFoundError:
            raise AblationError(f"{self.store_file} vanished during the run (deleted or moved); the trials it held "
                                f"are lost unless you put it back; then resume the run") from None
        except OSError as error:
            raise AblationError(f"cannot check {self.store_file}: {error.strerror or error}") from None
        return info.st_dev, info.st_ino

    def _check_ledger(self) -> set[str]:
        """On resume: every trial of the ledger must be in the store; trials the store holds beyond
        it (finished by workers after their coordinator died) join the ledger."""
        ledger = self.folder.finished()
        done = [r.spec.trial_id for r in self.recorded() if r.outcome != Outcome.ERROR]
        if ledger is None:  # a run folder of an older version: start the ledger from the store
            log.warning("ablation.no_ledger", run=str(self.folder.path), trials=len(done))
            self.folder.note_finished(done)
            return set(done)
        noted = set(ledger)
        self._refuse_lost(noted, set(done), when="holds")
        extra = [trial_id for trial_id in done if trial_id not in noted]
        if extra:
            self.folder.note_finished(extra)
        return noted | set(extra)

    def _refuse_lost(self, noted: set[str], stored: set[str], when: str) -> None:
        lost = sorted(noted - stored)
        if lost:
            shown = ", ".join(lost[:3]) + (", ..." if len(lost) > 3 else "")
            raise AblationError(
                f"{self._store_name()} {when} only {len(noted) - len(lost)} of the {len(noted)} finished trials "
                f"recorded in {self.folder.ledger_path} (missing: {shown}); it was deleted, emptied or replaced. "
                "Put the original file back to resume, or start a new run")

    def check_store(self, full: bool = True) -> None:
        """Fail if the store file was replaced or deleted, or (``full``) lost trials of the ledger."""
        if self._identity() != self.store_identity:
            raise AblationError(f"{self.store_file} was replaced during the run (it is not the file the run opened); "
                                "put the original back, then resume the run")
        if full and self.store.persistent:
            stored = {r.spec.trial_id for r in self.recorded() if r.outcome != Outcome.ERROR}
            self._refuse_lost(self.ledger, stored, when="now holds")
            self._checked_at = time.monotonic()

    def _note(self, result: TrialResult) -> None:
        if store_failed(result):  # every later trial would fail the same way: stop, resume once fixed
            raise StateStoreError(f"{result.detail} (trial {result.spec.trial_id}); finished trials are recorded: "
                                  "resume the run once the store can be written")
        self.check_store(full=time.monotonic() - self._checked_at >= FULL_CHECK_EVERY_S)
        if result.outcome != Outcome.ERROR and result.spec.trial_id not in self.ledger:
            self.folder.note_finished([result.spec.trial_id])
            self.ledger.add(result.spec.trial_id)

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
        if not self.store.persistent:  # checked before the run folder was made; a store may still change its mind
            raise _not_persistent(self.executor_name, self.scenario)
        if self.executor_name == "process":
            return ProcessExecutor(scenario_json, str(self.folder.path), self.workers, self.concurrency)
        return self._ray_executor(scenario_json)

    def _ray_executor(self, scenario_json: dict[str, Any]) -> Any:
        """Ray workers write nothing here: what they send is written by this process (``relay.py``)."""
        from ..loop.response_cache import CacheSettings, ResponseCache
        from .ray_executor import CONNECT_TIMEOUT_S, RayExecutor
        from .relay import RelayedWrites

        settings = CacheSettings.recorded(self.folder.path)
        cache = ResponseCache(settings.path(self.folder.path), read=settings.read) if settings.enabled else None
        writes = RelayedWrites(self.store, str(self.folder.path), cache)
        return RayExecutor(scenario_json, writes, self.workers, self.address, self.concurrency,
                           bag_storage=self.runner.bag_storage, cache=cache is not None,
                           connect_timeout_s=self.connect_timeout_s or CONNECT_TIMEOUT_S)

    def redraw_missing_trajectories(self) -> int:
        """Draw the pictures of recorded trials that have none (see ``ScenarioRunner``)."""
        drawn = self.runner.draw_missing_trajectories(
            [r for r in self.recorded() if r.outcome != Outcome.ERROR])  # error trials run again
        if drawn:
            log.info("ablation.redrawn", run=str(self.folder.path), pictures=drawn)
        return drawn

    def run(self, on_result: Callable[[TrialResult], None] | None = None) -> list[TrialResult]:
        """Run every pending trial; return all results of the run (earlier ones included).

        On any exception (KeyboardInterrupt from Ctrl-C or SIGTERM included) the workers are
        killed at once rather than waited for; what they were running is re-run on resume.
        """
        if self.resumed:
            self.redraw_missing_trajectories()
        pending = self.pending()
        log.info("ablation.start", run=str(self.folder.path), pending=len(pending), executor=self.executor_name)
        fresh: list[TrialResult] = []
        executor = self._executor()
        try:
            for result in executor.run(pending):
                if self.executor_name == "process":
                    self.store.end_trial(result)  # idempotent: the worker's store already wrote it
                self._note(result)
                fresh.append(result)
                if on_result is not None:
                    on_result(result)
        except BaseException:
            executor.abort()
            raise
        executor.close()
        self.check_store()
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
