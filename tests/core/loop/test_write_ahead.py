"""A motion that ran is always on record: a store failing at any write of a trial leaves every
command the environment executed in the store (as planned or executed), and ends the trial as
``error`` with a one-line detail instead of raising."""

from __future__ import annotations

import pytest

from safeembodai_core import run_guarded_trial
from safeembodai_core.contracts.components import StateStore
from safeembodai_core.errors import StateStoreError
from safeembodai_core.loop import Defences
from safeembodai_core.models import Outcome
from safeembodai_core.testing import CorridorWorld, ReplayBackend, answer, straight, turn
from safeembodai_plugins.state.memory_store import MemoryStateStore

STEPS = 4
TRIAL = "trial"
# each step several signals; step 2 needs a retry (its first answer does not parse)
SCRIPT = [
    answer(turn(10), straight(100), turn(10, "right")),
    "not an answer at all",
    answer(straight(80), turn(20), straight(60)),
    answer(turn(15, "right"), straight(120)),
    answer(straight(50), turn(5), straight(50), turn(5, "right")),
]
FAILURES = [StateStoreError("disk full"), OverflowError("Python int too large"), RuntimeError("store bug")]


class LoggingWorld(CorridorWorld):
    """The corridor, logging every command it executed (across resets)."""

    def __init__(self):
        super().__init__()
        self.log = []

    def execute(self, signal):
        self.log.append(signal)
        return super().execute(signal)


class FlakyStore(StateStore):
    """A memory store whose ``fail_at``-th write (begin, step or end; counted from 1) raises."""

    def __init__(self, fail_at: int | None = None, error: Exception = StateStoreError("disk full")):
        self.inner, self.fail_at, self.error = MemoryStateStore(), fail_at, error
        self.writes = 0

    def _write(self, method, *args):
        self.writes += 1
        if self.writes == self.fail_at:
            raise self.error
        method(*args)

    def begin_trial(self, spec):
        self._write(self.inner.begin_trial, spec)

    def record_step(self, record):
        self._write(self.inner.record_step, record)

    def end_trial(self, result):
        self._write(self.inner.end_trial, result)

    def reference_state(self, trial_id, step):
        return self.inner.reference_state(trial_id, step)

    def steps(self, trial_id):
        return self.inner.steps(trial_id)


def run(store: FlakyStore, world: LoggingWorld):
    defences = Defences(state_management=True)
    return run_guarded_trial(world, ReplayBackend(*SCRIPT), defences=defences, max_steps=STEPS, state=store,
                             perception="text", trial_id=TRIAL)


def on_record(store: FlakyStore) -> list:
    """Every command the store says ran or may have run, in order."""
    commands = []
    for record in store.inner.steps(TRIAL):
        commands += record.planned if record.status == "executing" else [item.signal for item in record.executed]
    return commands


def writes_of_a_clean_trial() -> int:
    store, world = FlakyStore(), LoggingWorld()
    result, steps = run(store, world)
    assert result.outcome == Outcome.TIMEOUT and len(steps) == STEPS
    assert on_record(store) == world.log and len(world.log) == 12
    return store.writes


def test_a_clean_trial_writes_each_planned_step_ahead_and_after():
    assert writes_of_a_clean_trial() == 1 + 2 * STEPS + 1  # begin, (plan, results) per step, end


@pytest.mark.parametrize("fail_at", range(1, 1 + 2 * STEPS + 2))
def test_a_store_failing_at_any_write_leaves_every_executed_command_on_record(fail_at):
    for error in FAILURES:
        store, world = FlakyStore(fail_at, error), LoggingWorld()
        result, _ = run(store, world)  # never raises
        assert store.writes >= fail_at, "the failure was never injected"
        assert result.outcome == Outcome.ERROR
        assert result.detail.startswith("state store could not") and "\n" not in result.detail
        recorded = on_record(store)
        assert world.log == recorded[:len(world.log)], f"write {fail_at} ({error!r}): a command ran off the record"
        if fail_at == 1:  # begin_trial failed: the robot never moved
            assert world.log == []


def test_a_plan_that_cannot_be_stored_is_not_executed():
    store, world = FlakyStore(fail_at=1 + 2 * 1 + 1), LoggingWorld()  # the plan of step 2
    result, steps = run(store, world)
    assert result.outcome == Outcome.ERROR and "plan of step 2" in result.detail
    assert "nothing of it ran" in result.detail
    assert [s.step for s in steps] == [1] and len(world.log) == 3  # step 1's three commands only


def test_results_that_cannot_be_stored_leave_the_plan_on_record_as_executing():
    store, world = FlakyStore(fail_at=1 + 2 * 1 + 2), LoggingWorld()  # the results of step 2
    result, steps = run(store, world)
    assert result.outcome == Outcome.ERROR and "results of step 2" in result.detail
    assert [s.status for s in steps] == ["done", "executing"]
    assert steps[1].executed == [] and [s.describe() for s in steps[1].planned] == [
        "straight forward 80 mm", "turn left 20 deg", "straight forward 60 mm"]
    assert world.log[3:] == steps[1].planned


def test_a_result_that_cannot_be_stored_ends_the_trial_as_error_and_says_how_it_had_ended():
    store, world = FlakyStore(fail_at=1 + 2 * STEPS + 1), LoggingWorld()
    result, steps = run(store, world)
    assert result.outcome == Outcome.ERROR and len(steps) == STEPS
    assert "record the trial's result" in result.detail and "had ended timeout" in result.detail
    assert store.inner.results()[0].outcome == Outcome.ERROR  # the second try stored the error
