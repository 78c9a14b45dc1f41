"""Where trials run: in this process, in a pool of worker processes, or on a Ray cluster.

Every executor yields results as trials finish, in completion order. Results do not depend on the
executor: a trial's seed comes from the scenario and its index only, and each worker builds its
own plugins, environments and store from the recorded scenario. Workers load installed plugins
(entry points), not inline ones.
"""

from __future__ import annotations

import os
import queue
import threading
from typing import Any, Iterator

from ..errors import SafeEmbodAIError
from ..models import TrialResult, TrialSpec
from .warm_start import start_warm_server, worker_context

#: How often the coordinator looks for a dead worker while it waits for results.
POLL_S = 0.5
#: The environment variable that tells a worker how many workers split a backend's rate limits.
RATE_SHARE = "SAFEEMBODAI_RATE_SHARE"


def build_worker_runner(scenario_json: dict[str, Any], run_dir: str, plugins: Any = None, state: Any = None) -> Any:
    """What every worker thread (of a process or a Ray actor) runs trials with: its own worlds, built
    from the recorded scenario; ``plugins`` and ``state`` (a :class:`.shared_store.SharedStateStore`)
    may be shared by a process's threads, else it builds its own."""
    from ..plugins import load_plugins
    from ..runner import ScenarioRunner
    from ..scenario import Scenario

    scenario = Scenario.model_validate(scenario_json)
    return ScenarioRunner(scenario, plugins or load_plugins(), run_dir=run_dir, save_trajectories=True, state=state)


def _worker_logging() -> None:
    """Logs go to a copy of stderr: a thread's ``silenced`` block (pybullet's chatter sent to
    /dev/null through the process-wide descriptors 1 and 2) must not swallow another thread's warning."""
    import sys

    from ..logs import configure_logging

    try:
        sys.stderr = os.fdopen(os.dup(2), "w", buffering=1, encoding="utf-8", errors="replace")
    except OSError:  # no stderr to copy: logs go where they would have gone
        pass
    configure_logging(os.environ.get("SAFEEMBODAI_WORKER_LOG_LEVEL", "warning"))


class RunnerPool:
    """Up to ``size`` trial runners, one per thread at a time, built when first needed."""

    def __init__(self, scenario_json: dict[str, Any], run_dir: str, size: int, plugins: Any = None) -> None:
        self.scenario_json, self.run_dir, self.size, self.plugins = scenario_json, run_dir, size, plugins
        self._idle: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._built = 0
        self._lock = threading.Lock()
        self._store: Any = None  # the threads' one state store, closed by the pool last
        self._shared: Any = None  # ... behind the one lock all threads share
        self._runners: list[Any] = []
        # one runner built at a time: the first trials start while the others are still being built,
        # instead of every thread sharing the GIL through its build
        self._building = threading.Lock()

    def run(self, spec: TrialSpec) -> TrialResult:
        runner = self._take(spec)
        try:
            return runner.run(spec)
        finally:
            self._idle.put(runner)

    def _take(self, spec: TrialSpec) -> Any:
        try:
            return self._idle.get_nowait()
        except queue.Empty:
            pass
        with self._lock:
            build = self._built < self.size
            if build:
                self._built += 1
        if not build:
            return self._idle.get()
        with self._building:
            if self.plugins is None:
                from ..plugins import load_plugins

                self.plugins = load_plugins()
            if self._store is None and self.size > 1:
                from .shared_store import SharedStateStore

                self._store = self._build_store()
                self._shared = SharedStateStore(self._store)
            runner = build_worker_runner(self.scenario_json, self.run_dir, self.plugins, self._shared)
            try:
                runner.environment(spec.environment)  # the world, the slow part of a build
            except Exception:  # the trial itself reports a world that cannot be built
                pass
        with self._lock:
            self._runners.append(runner)
        return runner

    def _build_store(self) -> Any:
        """The scenario's state store, built once for the pool's threads."""
        from ..runner import ScenarioRunner
        from ..scenario import Scenario

        scenario = Scenario.model_validate(self.scenario_json)
        return ScenarioRunner(scenario, self.plugins, run_dir=self.run_dir).build("state_store", scenario.state)

    def close(self) -> None:
        """Close every runner, then the shared store."""
        with self._lock:
            runners, self._runners = self._runners, []
        for runner in runners:
            runner.close()
        if self._store is not None:
            self._store.close()
            self._store = None


def _worker_main(scenario_json: dict[str, Any], run_dir: str, coordinator: int, concurrency: int,
                 tasks: Any, results: Any, workers: int = 1, lifeline: Any = None,
                 environ: dict[str, str] | None = None) -> None:
    """A worker process: ``concurrency`` threads, each taking specs from ``tasks`` until it meets
    None, running them and putting ``("result", result)`` (or ``("failed", message)``) on ``results``.
    ``workers`` processes split a backend's rate limits (``SAFEEMBODAI_RATE_SHARE``). ``environ``:
    the coordinator's environment variables when it started the worker (a worker forked from the
    fork server would otherwise have the server's, from an earlier moment); ``lifeline``: see
    :mod:`.lifeline`."""
    from .lifeline import bind_to_coordinator, orphaned
    from .run_folder import hold_worker_lock

    bind_to_coordinator(coordinator, lifeline)
    if environ is not None:
        os.environ.clear()
        os.environ.update(environ)
    os.environ[RATE_SHARE] = str(workers)
    _worker_logging()
    lock = hold_worker_lock(run_dir)  # noqa: F841 -- held until the process exits
    pool = RunnerPool(scenario_json, run_dir, concurrency)

    def work() -> None:
        while True:
            spec_json = tasks.get()
            if spec_json is None:
                return
            if orphaned(coordinator, lifeline):  # start no trial nobody will count
                os._exit(1)
            try:
                result = pool.run(TrialSpec.model_validate(spec_json))
            except BaseException as error:  # the runner records component failures itself: this is a bug
                results.put(("failed", f"{type(error).__name__}: {error}"))
                return
            results.put(("result", result.model_dump(mode="json")))

    threads = [threading.Thread(target=work, name=f"trial-{k}", daemon=True) for k in range(concurrency)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    pool.close()


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
    """``workers`` processes, each running up to ``concurrency`` trials at once in threads (a trial
    runner and its worlds per thread; one state store per process), fed from one queue; started
    with the first trial to run, forked from the warm fork server where there is one
    (:mod:`.warm_start`), else spawned.

    Threads suit trials that wait (a remote model answers in seconds); processes suit trials that
    compute (the mock pilot, many rooms). Results come back in completion order.
    """

    def __init__(self, scenario_json: dict[str, Any], run_dir: str, workers: int, concurrency: int = 1) -> None:
        context = worker_context()
        self.scenario_json = scenario_json
        self.tasks, self.results = context.Queue(), context.Queue()
        self.workers, self.concurrency = workers, concurrency
        # the workers' lifeline: the coordinator holds the only writing end until the workers are done
        self._lifeline, self._alive = context.Pipe(duplex=False)
        self.processes = [context.Process(target=_worker_main, name=f"safeembodai-worker-{k}", daemon=True,
                                          args=(scenario_json, run_dir, os.getpid(), concurrency, self.tasks,
                                                self.results, workers, self._lifeline, dict(os.environ)))
                          for k in range(workers)]

    def run(self, specs: list[TrialSpec]) -> Iterator[TrialResult]:
        if not specs:  # nothing to run: no worker is started
            return
        start_warm_server(self.scenario_json)  # nothing if the command started it already
        for process in self.processes:
            process.start()
        self._lifeline.close()  # the workers hold the reading end
        for spec in specs:
            self.tasks.put(spec.model_dump(mode="json"))
        for _ in range(self.workers * self.concurrency):
            self.tasks.put(None)  # one stop per thread: workers end once the queue is drained
        remaining = len(specs)
        while remaining:
            try:
                kind, payload = self.results.get(timeout=POLL_S)
            except queue.Empty:
                if any(p.exitcode not in (None, 0) for p in self.processes) or all(
                        p.exitcode is not None for p in self.processes):
                    raise SafeEmbodAIError("a worker process died (killed or out of memory); finished trials are "
                                           "recorded: resume the run to finish the rest") from None
                continue
            if kind != "result":
                raise SafeEmbodAIError(f"a worker failed: {payload}; finished trials are recorded: resume the run "
                                       "to finish the rest")
            remaining -= 1
            yield TrialResult.model_validate(payload)

    def close(self) -> None:
        """Wait for the workers to finish (the run ended normally)."""
        for process in self.processes:
            if process.pid is not None:
                process.join()
        self._close_queues()

    def abort(self) -> None:
        """Kill the workers now (the run was interrupted or failed): the trials they were running
        are not recorded as finished and run again, from scratch, on resume."""
        started = [process for process in self.processes if process.pid is not None]
        for process in started:
            if process.is_alive():
                process.kill()
        for process in started:
            process.join()
        self._close_queues()

    def _close_queues(self) -> None:
        self._lifeline.close()
        self._alive.close()  # the workers' lifeline (they are gone: nothing reads it)
        for channel in (self.tasks, self.results):
            channel.cancel_join_thread()  # never block on data no worker will read
            channel.close()


class RayExecutor:
    """One Ray actor per worker on a (local or remote) Ray cluster, each running up to
    ``concurrency`` trials at once (a threaded actor, one trial runner per thread); needs the
    ``ray`` extra."""

    def __init__(self, scenario_json: dict[str, Any], run_dir: str, workers: int, address: str | None,
                 concurrency: int = 1) -> None:
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
            def __init__(self, scenario_json, run_dir, concurrency, workers):
                os.environ[RATE_SHARE] = str(workers)
                _worker_logging()
                self.pool = RunnerPool(scenario_json, run_dir, concurrency)

            def run(self, spec_json):
                return self.pool.run(TrialSpec.model_validate(spec_json)).model_dump(mode="json")

        self.concurrency = concurrency
        self.actors = [TrialWorker.options(max_concurrency=concurrency).remote(scenario_json, run_dir, concurrency,
                                                                               workers) for _ in range(workers)]

    def run(self, specs: list[TrialSpec]) -> Iterator[TrialResult]:
        queue_ = [spec.model_dump(mode="json") for spec in specs]
        load = {index: 0 for index in range(len(self.actors))}
        running: dict[Any, int] = {}
        while queue_ or running:
            for index in load:
                while queue_ and load[index] < self.concurrency:
                    running[self.actors[index].run.remote(queue_.pop(0))] = index
                    load[index] += 1
            done, _ = self.ray.wait(list(running), num_returns=1)
            for ref in done:
                load[running.pop(ref)] -= 1
                yield TrialResult.model_validate(self.ray.get(ref))

    def close(self) -> None:
        for actor in self.actors:
            self.ray.kill(actor)

    abort = close
