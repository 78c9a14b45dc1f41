"""One state store for all of a worker's trial threads (``ablate --concurrency``).

Each thread opening its own connection to the run's SQLite file made 128 threads queue on the
file's write lock, some longer than its 30 s timeout (a writer holding the lock waits for the GIL
like everyone else). A worker's threads now share one store, behind one lock, so they queue on
that lock instead: a store needs no thread safety of its own, and only the worker processes
contend for the file. A store that says it is :attr:`~..components.StateStore.thread_safe` (the
SQLite store: one connection behind its own lock) is called without that lock: measured at 64 in
flight, threads waited 0.3-0.7 s per step record on it while its holder re-took the GIL at every
SQLite call. The store is closed once, by the pool that made it.
"""

from __future__ import annotations

import threading
from typing import Iterable

from ..contracts.components import StateStore, StepFacts
from ..models import ReferenceState, StepRecord, TrialResult, TrialSpec


class SharedStateStore(StateStore):
    """``inner`` with every call made under one lock; :meth:`close` leaves ``inner`` open."""

    def __init__(self, inner: StateStore) -> None:
        self.inner = inner
        self._lock = _Unlocked() if getattr(inner, "thread_safe", False) is True else threading.RLock()

    def begin_trial(self, spec: TrialSpec) -> None:
        with self._lock:
            self.inner.begin_trial(spec)

    def record_step(self, record: StepRecord) -> None:
        with self._lock:
            self.inner.record_step(record)

    def reference_state(self, trial_id: str, step: int) -> ReferenceState | None:
        with self._lock:
            return self.inner.reference_state(trial_id, step)

    def end_trial(self, result: TrialResult) -> None:
        with self._lock:
            self.inner.end_trial(result)

    def steps(self, trial_id: str) -> list[StepRecord]:
        with self._lock:
            return self.inner.steps(trial_id)

    def step_facts(self, trial_ids: Iterable[str]) -> dict[str, StepFacts]:
        with self._lock:
            return self.inner.step_facts(trial_ids)

    def results(self) -> list[TrialResult]:
        with self._lock:
            return self.inner.results()

    @property
    def persistent(self) -> bool:
        return self.inner.persistent

    @property
    def thread_safe(self) -> bool:
        return True

    def close(self) -> None:
        """Nothing: the pool closes ``inner`` once every thread is done with it."""


class _Unlocked:
    """A lock that is not one, for a store that keeps its own."""

    def __enter__(self) -> None:
        return None

    def __exit__(self, *exc: object) -> None:
        return None
