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
