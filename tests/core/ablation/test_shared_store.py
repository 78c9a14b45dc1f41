"""A worker's trial threads share one state store behind one lock (``ablation/shared_store.py``)."""

from __future__ import annotations

import threading

from safeembodai_core.ablation.shared_store import SharedStateStore
from safeembodai_core.models import Outcome, TrialResult, TrialSpec


class Fragile:
    """A store that notices two calls at once (as a store without thread safety would break)."""

    def __init__(self):
        self.inside, self.overlaps, self.finished, self.closed = 0, 0, [], False
        self.persistent = True

    def _enter(self):
        self.inside += 1
        self.overlaps += self.inside > 1
        threading.Event().wait(0.001)
        self.inside -= 1

    def begin_trial(self, spec):
        self._enter()

    def end_trial(self, result):
        self._enter()
        self.finished.append(result.spec.trial_id)

    def results(self):
        return []

    def close(self):
        self.closed = True


def test_calls_from_many_threads_never_overlap_and_close_leaves_the_store_open():
    inner = Fragile()
    shared = SharedStateStore(inner)

    def trial(k):
        spec = TrialSpec(trial_id=f"OF/a/c/{k}", environment="OF", arm="a", condition="c", index=k, seed=k)
        shared.begin_trial(spec)
        shared.end_trial(TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=1))

    threads = [threading.Thread(target=trial, args=(k,)) for k in range(32)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert inner.overlaps == 0 and len(inner.finished) == 32
    assert shared.persistent is True
    shared.close()
    assert not inner.closed  # the pool that made the store closes it, once


class Sturdy(Fragile):
    """A store that says it is thread safe: the shared store adds no lock of its own."""

    thread_safe = True


def _many_threads(store, count=16):
    def trial(k):
        spec = TrialSpec(trial_id=f"OF/a/c/{k}", environment="OF", arm="a", condition="c", index=k, seed=k)
        store.begin_trial(spec)
        store.end_trial(TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=1))

    threads = [threading.Thread(target=trial, args=(k,)) for k in range(count)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()


def test_a_thread_safe_store_is_called_without_the_shared_lock():
    inner = Sturdy()
    _many_threads(SharedStateStore(inner), 32)
    assert inner.overlaps > 0 and len(inner.finished) == 32  # calls overlapped: nothing serialised them


def test_the_sqlite_store_is_thread_safe_under_overlapping_step_records(tmp_path):
    from safeembodai_core.models import StepRecord
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    inner = SqliteStateStore(tmp_path / "results.sqlite")
    assert inner.thread_safe is True
    shared = SharedStateStore(inner)
    errors = []

    def trial(k):
        try:
            spec = TrialSpec(trial_id=f"OF/a/c/{k}", environment="OF", arm="a", condition="c", index=k, seed=k)
            shared.begin_trial(spec)
            for step in range(1, 6):
                assert (shared.reference_state(spec.trial_id, step) is None) == (step == 1)
                shared.record_step(StepRecord(trial_id=spec.trial_id, step=step, instruction=f"go {k}"))
            shared.end_trial(TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=5))
        except BaseException as error:  # noqa: BLE001 -- reported below
            errors.append(error)

    threads = [threading.Thread(target=trial, args=(k,)) for k in range(24)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors
    assert len(shared.results()) == 24
    assert all([s.step for s in shared.steps(f"OF/a/c/{k}")] == [1, 2, 3, 4, 5] for k in range(24))
    assert shared.steps("OF/a/c/7")[0].instruction == "go 7"
    inner.close()
