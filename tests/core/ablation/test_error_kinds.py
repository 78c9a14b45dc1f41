"""TrialResult.error_kind: set where a trial's error is caught, read by the report and the engine."""

from __future__ import annotations

import pytest

from safeembodai_core import run_guarded_trial
from safeembodai_core.ablation.error_kinds import all_errored, crashed, error_kind, store_failed
from safeembodai_core.contracts.components import BackendReply, LLMBackend
from safeembodai_core.errors import BackendError, EnvironmentError_
from safeembodai_core.loop.trial import error_result
from safeembodai_core.models import Outcome, TrialResult, TrialSpec
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.testing import CorridorWorld, answer, turn

SPEC = TrialSpec(trial_id="OF/a/c/0", environment="OF", arm="a", condition="c", index=0, seed=0)


class Raising(LLMBackend):
    def __init__(self, error: BaseException) -> None:
        self.error = error

    def complete(self, prompt, rng):
        raise self.error


class Fine(LLMBackend):
    def complete(self, prompt, rng):
        return BackendReply(text=answer(turn(10)))


class UnwritableStore:
    """The memory store's interface, but a step cannot be written (a full disk)."""

    persistent = False

    def begin_trial(self, spec):
        pass

    def record_step(self, record):
        raise OSError(28, "No space left on device")

    def reference_state(self, trial_id, step):
        return None

    def end_trial(self, result):
        pass

    def steps(self, trial_id):
        return []

    def close(self):
        pass


@pytest.fixture(scope="module")
def plugins():
    return load_plugins(environ={})


@pytest.mark.parametrize("error, kind", [
    (BackendError("llm backend 'x' gave up after 3 tries: server error"), "backend"),
    (EnvironmentError_("corridor: the world fell over"), "reported"),
    (ZeroDivisionError("division by zero"), "crash"),
])
def test_the_trial_loop_names_what_ended_the_trial(plugins, error, kind):
    result, _ = run_guarded_trial(CorridorWorld(), Raising(error), max_steps=2, plugins=plugins)
    assert result.outcome == Outcome.ERROR and result.error_kind == kind and error_kind(result) == kind
    assert crashed(result) is (kind == "crash")


def test_a_store_that_cannot_write_is_a_store_error_and_stops_an_ablation(plugins):
    result, _ = run_guarded_trial(CorridorWorld(), Fine(), max_steps=2, plugins=plugins, state=UnwritableStore())
    assert result.error_kind == "store" and store_failed(result)


class UnreadableStore(UnwritableStore):
    """Steps are written, but R_{i-1} cannot be read back (a third-party store's plain exception)."""

    def record_step(self, record):
        pass

    def reference_state(self, trial_id, step):
        raise RuntimeError("connection reset by peer")


def test_a_store_that_cannot_read_the_reference_state_is_a_store_error(plugins):
    result, _ = run_guarded_trial(CorridorWorld(), Fine(), max_steps=2, plugins=plugins, state=UnreadableStore(),
                                  defences={"state_management": True})
    assert result.outcome == Outcome.ERROR and result.error_kind == "store" and store_failed(result)
    assert not crashed(result)
    assert result.detail == ("state store could not read the reference state of step 1: "
                             "RuntimeError: connection reset by peer")


def test_build_failures_and_finished_trials():
    assert error_result(SPEC, "components could not be built: x").error_kind == "build"
    finished = TrialResult(spec=SPEC, outcome=Outcome.TIMEOUT, steps=3)
    assert finished.error_kind is None and error_kind(finished) is None


def test_the_field_wins_over_the_detail_and_old_results_are_read_off_their_detail():
    # a backend whose provider text looks like an exception name is no crash
    outage = TrialResult(spec=SPEC, outcome=Outcome.ERROR, steps=0, detail="RateLimitError: slow down",
                         error_kind="backend")
    assert not crashed(outage) and error_kind(outage) == "backend"
    # the engine stops on the field, whatever the detail says
    assert store_failed(TrialResult(spec=SPEC, outcome=Outcome.ERROR, steps=0, detail="disk full", error_kind="store"))
    stored_before = TrialResult.model_validate_json(
        '{"spec": %s, "outcome": "error", "steps": 0, "detail": "state store could not record it: locked"}'
        % SPEC.model_dump_json())
    assert stored_before.error_kind is None and error_kind(stored_before) == "store"
    for detail, kind in [("KeyError: 'x'", "crash"), ("scripted backend: no answer left after 2", "backend"),
                         ("components could not be built: plugin 'x': boom", "build"), ("MO: closed", "reported")]:
        assert error_kind(TrialResult(spec=SPEC, outcome=Outcome.ERROR, steps=0, detail=detail)) == kind


def test_all_errored_says_so_in_one_line():
    ok = TrialResult(spec=SPEC, outcome=Outcome.COMPLETED, steps=3)
    down = TrialResult(spec=SPEC, outcome=Outcome.ERROR, steps=0, detail="llm backend down", error_kind="backend")
    assert all_errored([ok, down]) is None and all_errored([]) is None
    reason = all_errored([down, down.model_copy(update={"error_kind": "crash"})])
    assert reason.startswith("every one of the 2 trials ended in error (1 backend, 1 crash)") and "\n" not in reason
