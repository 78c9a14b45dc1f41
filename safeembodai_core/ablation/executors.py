"""Where trials run: in this process, in a pool of worker processes, or on a Ray cluster.

Every executor yields results as trials finish, in completion order. Results do not depend on the
executor: a trial's seed comes from the scenario and its index only, and each worker builds its
own plugins, environments and store from the recorded scenario. Workers load installed plugins
(entry points), not inline ones.
"""

from __future__ import annotations

import multiprocessing
import os
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Iterator

from ..errors import SafeEmbodAIError
from ..models import TrialResult, TrialSpec

_WORKER: dict[str, Any] = {}


def build_worker_runner(scenario_json: dict[str, Any], run_dir: str) -> Any:
    """What every worker (process or Ray actor) runs trials with: its own plugins, worlds and store."""
    from ..logs import configure_logging
    from ..plugins import load_plugins
    from ..runner import ScenarioRunner
    from ..scenario import Scenario

    configure_logging(os.environ.get("SAFEEMBODAI_WORKER_LOG_LEVEL", "warning"))
    scenario = Scenario.model_validate(scenario_json)
    return ScenarioRunner(scenario, load_plugins(), run_dir=run_dir, save_trajectories=True)


def _init_worker(scenario_json: dict[str, Any], run_dir: str, coordinator: int) -> None:
    from .lifeline import bind_to_coordinator
    from .run_folder import hold_worker_lock

    bind_to_coordinator(coordinator)
    _WORKER["lock"] = hold_worker_lock(run_dir)
    _WORKER["runner"] = build_worker_runner(scenario_json, run_dir)
    _WORKER["coordinator"] = coordinator


def _run_in_worker(spec_json: dict[str, Any]) -> dict[str, Any]:
    if os.getppid() != _WORKER["coordinator"]:  # the coordinator died: start no trial nobody will count
        os._exit(1)
    result = _WORKER["runner"].run(TrialSpec.model_validate(spec_json))
    return result.model_dump(mode="json")


class SerialExecutor:
    """Runs trials one after another in this process."""

    def __init__(self, runner: Any) -> None:
        self.runner = runner

    def run(self, specs: list[TrialSpec]) -> Iterator[TrialResult]:
        for spec in specs:
            yield self.runner.run(spec)

    def close(self) -> None:
        self.runner.close()

    abort = close


class ProcessExecutor:
    """A pool of ``workers`` spawned processes, each with one environment per label, reused."""

    def __init__(self, scenario_json: dict[str, Any], run_dir: str, workers: int) -> None:
        self.pool = ProcessPoolExecutor(
            max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
            initializer=_init_worker, initargs=(scenario_json, run_dir, os.getpid()),
        )
        self.workers = workers

    def run(self, specs: list[TrialSpec]) -> Iterator[TrialResult]:
        queue = list(specs)
        running: dict[Any, TrialSpec] = {}
        try:
            while queue or running:
                while queue and len(running) < 2 * self.workers:  # bounded: no burst of futures
                    spec = queue.pop(0)
                    running[self.pool.submit(_run_in_worker, spec.model_dump(mode="json"))] = spec
                done, _ = wait(running, return_when=FIRST_COMPLETED)
                for future in done:
                    spec = running.pop(future)
                    yield TrialResult.model_validate(future.result())
        except BrokenProcessPool:
            raise SafeEmbodAIError("a worker process died (killed or out of memory); finished trials are recorded: "
                                   "resume the run to finish the rest") from None

    def close(self) -> None:
        """Wait for the trials that run, then stop the workers (the run ended normally)."""
        self.pool.shutdown(wait=True, cancel_futures=True)

    def abort(self) -> None:
        """Kill the workers now (the run was interrupted or failed): the trials they were running
        are not recorded as finished and run again, from scratch, on resume."""
        for process in list((getattr(self.pool, "_processes", None) or {}).values()):
            process.kill()
        self.pool.shutdown(wait=True, cancel_futures=True)


class RayExecutor:
    """One Ray actor per worker on a (local or remote) Ray cluster; needs the ``ray`` extra."""

    def __init__(self, scenario_json: dict[str, Any], run_dir: str, workers: int, address: str | None) -> None:
        try:
            import ray
        except ImportError:
            raise SafeEmbodAIError('the ray executor needs the ray extra: pip install -e ".[ray]"') from None
        self.ray = ray
        # a run must not phone home: Ray's usage stats stay off unless the user turned them on
        os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
        if not ray.is_initialized():
            local = {"_node_ip_address": "127.0.0.1"} if address is None else {}
            ray.init(address=address, include_dashboard=False, log_to_driver=False,
                     ignore_reinit_error=True, configure_logging=False, **local)

        @ray.remote
        class TrialWorker:
            def __init__(self, scenario_json, run_dir):
                self.runner = build_worker_runner(scenario_json, run_dir)

            def run(self, spec_json):
                return self.runner.run(TrialSpec.model_validate(spec_json)).model_dump(mode="json")

        self.actors = [TrialWorker.remote(scenario_json, run_dir) for _ in range(workers)]

    def run(self, specs: list[TrialSpec]) -> Iterator[TrialResult]:
        from ray.util import ActorPool

        pool = ActorPool(self.actors)
        payload = [spec.model_dump(mode="json") for spec in specs]
        for result in pool.map_unordered(lambda actor, spec: actor.run.remote(spec), payload):
            yield TrialResult.model_validate(result)

    def close(self) -> None:
        for actor in self.actors:
            self.ray.kill(actor)

    abort = close
