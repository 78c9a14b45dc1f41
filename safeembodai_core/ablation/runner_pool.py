"""What a worker runs trials with: a pool of trial runners, one per thread, built when first needed.

Used by the worker processes of the process executor and by the Ray actors alike.
"""

from __future__ import annotations

import os
import queue
import threading
from typing import Any

from ..models import TrialResult, TrialSpec

#: The environment variable that tells a worker how many workers split a backend's rate limits.
RATE_SHARE = "SAFEEMBODAI_RATE_SHARE"


def build_worker_runner(scenario_json: dict[str, Any], run_dir: str | None, plugins: Any = None, state: Any = None,
                        outputs: Any = None) -> Any:
    """What every worker thread (of a process or a Ray actor) runs trials with: its own worlds, built
    from the recorded scenario; ``plugins`` and ``state`` (a :class:`.shared_store.SharedStateStore`,
    or a Ray worker's :class:`.relay.RelayStore`) may be shared by the threads, else it builds its own.
    ``outputs`` (a Ray worker's): where files, bags and replies go instead of ``run_dir``."""
    from ..plugin.manager import load_plugins
    from ..runs.runner import ScenarioRunner
    from ..scenario import Scenario

    scenario = Scenario.model_validate(scenario_json)
    return ScenarioRunner(scenario, plugins or load_plugins(), run_dir=run_dir, save_trajectories=True, state=state,
                          outputs=outputs)


def worker_logging() -> None:
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

    def __init__(self, scenario_json: dict[str, Any], run_dir: str | None, size: int, plugins: Any = None,
                 state: Any = None, outputs: Any = None) -> None:
        """``state`` and ``outputs``: a Ray worker's relay (``relay.py``), shared by every thread;
        else each process builds the scenario's store once for its threads, in ``run_dir``."""
        self.scenario_json, self.run_dir, self.size, self.plugins = scenario_json, run_dir, size, plugins
        self.outputs = outputs
        self._idle: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._built = 0
        self._lock = threading.Lock()
        self._store: Any = None  # the threads' one state store, closed by the pool last
        self._shared: Any = state  # ... behind the one lock all threads share (or the relay, given)
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
                from ..plugin.manager import load_plugins

                self.plugins = load_plugins()
            if self._shared is None and self.size > 1:
                from .shared_store import SharedStateStore

                self._store = self._build_store()
                self._shared = SharedStateStore(self._store)
            runner = build_worker_runner(self.scenario_json, self.run_dir, self.plugins, self._shared, self.outputs)
            try:
                runner.environment(spec.environment)  # the world, the slow part of a build
            except Exception:  # the trial itself reports a world that cannot be built
                pass
        with self._lock:
            self._runners.append(runner)
        return runner

    def _build_store(self) -> Any:
        """The scenario's state store, built once for the pool's threads."""
        from ..plugin.building import ComponentBuilder
        from ..scenario import Scenario

        return ComponentBuilder(Scenario.model_validate(self.scenario_json), self.plugins, self.run_dir).state_store()

    def close(self) -> None:
        """Close every runner, then the shared store."""
        with self._lock:
            runners, self._runners = self._runners, []
        for runner in runners:
            runner.close()
        if self._store is not None:
            self._store.close()
            self._store = None
