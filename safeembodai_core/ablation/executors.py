"""Where trials run on this machine: in this process, or in a pool of worker processes
(``ray_executor.py``: on a Ray cluster).

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
from .runner_pool import RATE_SHARE, RunnerPool, worker_logging
from .warm_start import start_warm_server, worker_context

#: How often the coordinator looks for a dead worker while it waits for results.
POLL_S = 0.5


class WorkersLost(SafeEmbodAIError):
    """The workers can run no more of the run's trials (killed, out of memory, a lost cluster):
    finished trials are recorded, a resume runs the rest."""


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
    from ..runs.folder import hold_worker_lock

    bind_to_coordinator(coordinator, lifeline)
    if environ is not None:
        os.environ.clear()
        os.environ.update(environ)
    os.environ[RATE_SHARE] = str(workers)
    worker_logging()
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
                    raise WorkersLost("a worker process died (killed or out of memory)") from None
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
