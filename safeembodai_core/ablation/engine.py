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
import time
from pathlib import Path
from typing import Any, Callable


from ..errors import StateStoreError
from ..models import Outcome, TrialResult, TrialSpec
from ..plugin.manager import Plugins
from ..runs.runner import ScenarioRunner
from ..scenario import Scenario
from .error_kinds import store_failed
from .executors import ProcessExecutor, SerialExecutor
from .plan import AblationError, RunPlan, check_resumable, not_persistent
from ..runs.folder import RunFolder, RunLock
from ..runs.trial_files import record_artefacts

from ..logs import get_logger

log = get_logger(__name__)

FULL_CHECK_EVERY_S = 2.0  # reading every result back costs O(trials): not after each trial of a fast run


class Ablation:
    """One ablation run of ``scenario`` in ``folder``.

    Built from a :class:`~.plan.RunPlan` (``plan``; :meth:`start`), it checks nothing again. Built
    directly, as a library user may, it runs the plan's checks itself with the options given, so a
    library user's run is refused where the CLI's would be."""

    def __init__(self, scenario: Scenario, plugins: Plugins, folder: RunFolder, *, resume: bool = False,
                 workers: int = 1, executor: str | None = None, address: str | None = None,
                 bags: str | None = None, concurrency: int = 1, cache: Any = None,
                 connect_timeout_s: float | None = None, recordings: bool = False,
                 plan: RunPlan | None = None) -> None:
        if plan is None:
            plan = RunPlan.prepare(scenario, plugins, workers=workers, concurrency=concurrency, executor=executor,
                                   address=address, connect_timeout_s=connect_timeout_s, bags=bags,
                                   recordings=recordings, cache=cache, resume=folder.path if resume else None)
        self.plan = plan
        self.scenario, self.plugins, self.folder = plan.scenario, plan.plugins, folder
        self.workers, self.address, self.concurrency = plan.workers, plan.address, plan.concurrency
        self.connect_timeout_s = plan.connect_timeout_s
        self.executor_name = plan.executor
        if not resume:
            folder.start(self.scenario)
        elif plan.resume is None or Path(plan.resume) != folder.path:  # the plan checked no folder, or another
            check_resumable(folder.path, self.scenario, self.plugins)
        self.lock = RunLock(folder.path)
        self.lock.acquire()
        # before any runner: every worker's reads them from the folder
        record_artefacts(folder.path, bags=plan.bags, recordings=plan.recordings)
        if plan.cache is not None:  # a CacheSettings (what the run recorded on a resume without cache options)
            plan.cache.write(folder.path)
        self.runner = ScenarioRunner(self.scenario, self.plugins, run_dir=folder.path, save_trajectories=True)
        try:
            self.store = self.runner.state
            store_path = getattr(self.store, "path", None)  # a store kept in a file says where
            self.store_file = Path(store_path) if isinstance(store_path, (str, Path)) else None
            self.store_identity = self._identity()
            self.ledger = self._check_ledger() if resume else set()
        except BaseException:
            self.close()
            raise
        self.resumed = resume
        self._checked_at = time.monotonic()

    @classmethod
    def start(cls, plan: RunPlan, out_root: str | Path = "runs") -> "Ablation":
        """The run ``plan`` prepared, in a new run folder under ``out_root`` (or in the folder it
        resumes, :attr:`RunPlan.resume`, which must have recorded the same scenario), ready to
        :meth:`run`; the caller closes it."""
        resume = plan.resume
        folder = RunFolder(resume) if resume is not None else RunFolder.create(out_root, plan.scenario)
        return cls(plan.scenario, plan.plugins, folder, resume=resume is not None, plan=plan)

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
            raise not_persistent(self.executor_name, self.scenario)
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
                           artefacts=self.runner.artefacts.settings, cache=cache is not None,
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
        cap = self.plan.cap
        try:
            for result in executor.run(pending):
                if self.executor_name == "process":
                    self.store.end_trial(result)  # idempotent: the worker's store already wrote it
                self._note(result)
                fresh.append(result)
                if on_result is not None:
                    on_result(result)
                if cap is not None:  # the trial is recorded: the cap stops the ones after it
                    cap.add(result, more=len(fresh) < len(pending))
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
