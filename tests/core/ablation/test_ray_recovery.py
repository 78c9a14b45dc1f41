"""How the Ray executor meets lost and failing workers, with a stand-in for Ray (no cluster): a trial
cut off mid-way runs again on a replacement worker and is yielded once; a worker that cannot start
says why; a worker's own error names the trial; a whole trial without its end is refused."""

from __future__ import annotations

import sys
from types import SimpleNamespace

import pytest

from safeembodai_core.ablation.executors import WorkersLost
from safeembodai_core.ablation.ray_executor import RayExecutor
from safeembodai_core.ablation.relay import RelayError
from safeembodai_core.models import Outcome, TrialResult, TrialSpec


class RayActorError(Exception):
    actor_init_failed = False


class ActorDiedError(RayActorError):
    def __init__(self, message="", init_failed=False):
        super().__init__(message)
        self.actor_init_failed = init_failed


class RayTaskError(Exception):
    pass


class Ref:
    def __init__(self, value):
        self.value = value


class Stream:
    """A streaming generator's stand-in: each ``next`` gives a Ref to the next event (or error)."""

    def __init__(self, items):
        self.items = list(items)

    def __next__(self):
        if not self.items:
            raise StopIteration
        return Ref(self.items.pop(0))


def spec(k: int) -> TrialSpec:
    return TrialSpec(trial_id=f"E/a/c/{k}", scenario="s", environment="E", arm="a", condition="c", index=k, seed=k)


def events(s: TrialSpec):
    result = TrialResult(spec=s, outcome=Outcome.COMPLETED, steps=1).model_dump(mode="json")
    return [("node", "10.0.0.1/abcd"), ("begin", s.model_dump(mode="json")), ("end", result), ("done", result)]


def fake_ray(behaviour) -> SimpleNamespace:
    """``behaviour(actor_number, spec)`` gives the items of that actor's stream for ``spec``."""
    made = []

    def remote(cls):
        def options(**kwargs):
            def start(*args):
                number = len(made)
                made.append(number)
                run = SimpleNamespace(remote=lambda spec_json, replies: Stream(
                    behaviour(number, TrialSpec.model_validate(spec_json))))
                return SimpleNamespace(run=run, run_whole=run)
            return SimpleNamespace(remote=start)
        return SimpleNamespace(options=options)

    def get(ref):
        if isinstance(ref.value, BaseException):
            raise ref.value
        return ref.value

    exceptions = SimpleNamespace(RayActorError=RayActorError, ActorDiedError=ActorDiedError, RayTaskError=RayTaskError)
    return SimpleNamespace(is_initialized=lambda: True, remote=remote, get=get, kill=lambda actor: None,
                           wait=lambda refs, num_returns, timeout: (refs[:1], refs[1:]), nodes=list,
                           exceptions=exceptions, made=made)


class Writes:
    """The coordinator's writes, recorded."""

    def __init__(self):
        from safeembodai_core.ablation.relay import RelayedWrites
        from safeembodai_plugins.state.memory_store import MemoryStateStore

        self.store = MemoryStateStore()
        self.inner = RelayedWrites(self.store, "/nonexistent")

    def replies_for(self, spec):
        return {}

    def receive(self, spec, event):
        return self.inner.receive(spec, event)


def executor(monkeypatch, behaviour, workers=1):
    ray = fake_ray(behaviour)
    monkeypatch.setitem(sys.modules, "ray", ray)
    writes = Writes()
    return RayExecutor({}, writes, workers=workers, address=None), writes, ray


def test_a_trial_cut_off_runs_again_on_a_replacement_and_is_yielded_once(monkeypatch):
    def behaviour(actor, s):
        if actor == 0 and s.index == 1:  # the first worker's node is lost in the middle of trial 1
            return events(s)[:2] + [ActorDiedError("node lost")]
        return events(s)

    ray_executor, writes, ray = executor(monkeypatch, behaviour)
    results = [r.spec.trial_id for r in ray_executor.run([spec(0), spec(1), spec(2)])]
    assert sorted(results) == ["E/a/c/0", "E/a/c/1", "E/a/c/2"] and len(results) == 3
    assert ray.made == [0, 1]  # one replacement worker
    assert sorted(writes.store.results_by_id) == sorted(results)


def test_a_worker_that_cannot_start_says_why_at_once(monkeypatch):
    def behaviour(actor, s):
        return [ActorDiedError("Traceback ...\nModuleNotFoundError: No module named 'safeembodai_core'",
                               init_failed=True)]

    ray_executor, _, ray = executor(monkeypatch, behaviour, workers=2)
    with pytest.raises(WorkersLost, match="could not start on its node: ModuleNotFoundError: No module named"):
        list(ray_executor.run([spec(0)]))
    assert ray.made == [0, 1]  # no replacement tried


def test_a_workers_own_error_names_the_trial(monkeypatch):
    ray_executor, _, _ = executor(monkeypatch, lambda actor, s: [RayTaskError("Traceback...\nValueError: boom")])
    with pytest.raises(RelayError, match="failed on trial E/a/c/0: ValueError: boom"):
        list(ray_executor.run([spec(0)]))


def test_a_trial_lost_every_time_stops_the_run(monkeypatch):
    ray_executor, _, _ = executor(monkeypatch, lambda actor, s: events(s)[:2] + [ActorDiedError("lost")])
    with pytest.raises(WorkersLost, match="cut off 3 times"):
        list(ray_executor.run([spec(0)]))


def test_a_done_without_its_end_is_refused(monkeypatch):
    ray_executor, _, _ = executor(monkeypatch, lambda actor, s: [e for e in events(s) if e[0] != "end"])
    with pytest.raises(RelayError, match="without storing its result first"):
        list(ray_executor.run([spec(0)]))
