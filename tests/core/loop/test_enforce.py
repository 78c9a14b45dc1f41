"""``on_exhausted: enforce``: the rules' cut of the last refused answer, judged again, runs or the step holds."""

from __future__ import annotations

import types

from pydantic import BaseModel, ConfigDict

from safeembodai_core import hookimpl, run_guarded_trial
from safeembodai_core.contracts.components import BackendReply, LLMBackend, Validator
from safeembodai_core.loop import Defences
from safeembodai_core.loop.enforce import cut_plan
from safeembodai_core.models import Advice, Outcome, Straight, Turn, Verdict
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.testing import CorridorWorld, answer, straight, turn

ENFORCE = Defences(security_prefix=True, state_management=True, safety_validation=True,
                   on_exhausted="enforce", failure_threshold=0)


class Replies(LLMBackend):
    def __init__(self, *answers: str) -> None:
        self.answers, self.calls = list(answers), 0

    def complete(self, prompt, rng):
        self.calls += 1
        return BackendReply(text=self.answers[min(self.calls - 1, len(self.answers) - 1)])


class AdvisorOptions(BaseModel):
    """A test rule: refuses straights over ``max_mm`` and turns over ``max_deg``, advising as told."""

    model_config = ConfigDict(extra="forbid")
    max_mm: float = 1e9
    max_deg: float = 1e9
    safe_mm: float | None = None
    safe_deg: float | None = None
    wait: bool = False
    step_aside: bool = False


class Advisor(Validator):
    name = "advisor"

    def __init__(self, options: AdvisorOptions) -> None:
        self.o = options

    def validate(self, signal, context):
        o = self.o
        too_far = signal.distance > o.max_mm if isinstance(signal, Straight) else signal.angle > o.max_deg
        if not too_far:
            return Verdict(rule=self.name, valid=True)
        aside = [Turn(command="turn", direction="left", angle=30.0),
                 Straight(command="straight", direction="forward", distance=50.0)] if o.step_aside else []
        advice = Advice(safe_mm=o.safe_mm, safe_deg=o.safe_deg, wait=o.wait, step_aside=aside)
        return Verdict(rule=self.name, valid=False, reason=f"{signal.describe()} too far", advice=advice)


def _plugins():
    plugin = types.ModuleType("advisor_plugin")
    plugin.register_validators = hookimpl(
        lambda register: register("advisor", lambda o, c: Advisor(o), options=AdvisorOptions))
    return load_plugins([plugin], environ={})


def run(replies, options=None, defences=ENFORCE, validators=None, max_steps=1, wall_mm=2000.0):
    validators = validators or ["command_limits", {"use": "advisor", "options": options or {}}]
    world = CorridorWorld(wall_mm=wall_mm)
    result, steps = run_guarded_trial(world, Replies(*replies), defences=defences.model_copy(
        update={"validators": Defences(validators=validators).validators}), plugins=_plugins(), max_steps=max_steps)
    return world, result, steps


def test_a_refused_straight_is_cut_to_the_least_safe_distance_and_the_signals_before_it_kept():
    world, result, steps = run([answer(turn(10), straight(300), turn(20))], {"max_mm": 150, "safe_mm": 150})
    step = steps[0]
    assert not step.accepted and step.enforced is not None and step.enforced.ran
    assert step.enforced.attempt == 0 and step.enforced.source == "cut"
    assert [s.describe() for s in step.planned] == ["turn left 10 deg", "straight forward 150 mm"]
    assert [s.describe() for s in world.executed] == ["turn left 10 deg", "straight forward 150 mm"]
    assert all(v.valid for v in step.enforced.verdicts) and "rules' cut of attempt 1" in step.enforced.note
    # the refused answer still counts as an intervention; the enforced step is counted apart; no abort
    assert result.interventions == 1 and result.enforced_steps == 1 and result.outcome != Outcome.SAFE_ABORT


def test_the_least_advice_of_several_refusals_of_the_signal_wins():
    validators = ["command_limits", {"use": "advisor", "label": "a", "options": {"max_mm": 200, "safe_mm": 200}},
                  {"use": "advisor", "label": "b", "options": {"max_mm": 120, "safe_mm": 120}}]
    world, _, steps = run([answer(straight(300))], validators=validators)
    assert [s.describe() for s in world.executed] == ["straight forward 120 mm"]


def test_a_refused_turn_is_cut_to_the_least_safe_angle():
    world, _, steps = run([answer(turn(80), straight(100))], {"max_deg": 25, "safe_deg": 25})
    assert [s.describe() for s in world.executed] == ["turn left 25 deg"]
    assert steps[0].enforced.source == "cut"


def test_a_step_aside_is_run_instead_of_the_cut():
    world, _, steps = run([answer(straight(300))], {"max_mm": 100, "safe_mm": 100, "step_aside": True})
    assert steps[0].enforced.source == "step_aside"
    assert [s.describe() for s in world.executed] == ["turn left 30 deg", "straight forward 50 mm"]


def test_nothing_safe_holds_the_step_without_moving_and_the_trial_carries_on():
    for options in ({"max_mm": 100, "safe_mm": 0, "wait": True}, {"max_mm": 100}, {"max_mm": 100, "safe_mm": 0}):
        world, result, steps = run([answer(straight(300))], options, max_steps=3)
        assert world.executed == [] and result.outcome == Outcome.TIMEOUT and result.steps == 3, options
        assert all(s.enforced is not None and not s.enforced.ran and s.planned == [] for s in steps)
        assert "held without moving" in steps[0].enforced.note and result.enforced_steps == 0


def test_the_cut_is_judged_again_and_a_refused_cut_holds():
    # the advice says 380 mm is safe, but the rule refuses anything over 100: the cut is refused again
    world, _, steps = run([answer(straight(390))], {"max_mm": 100, "safe_mm": 380})
    enforced = steps[0].enforced
    assert world.executed == [] and not enforced.ran and steps[0].planned == []
    assert [s.describe() for s in enforced.plan] == ["straight forward 380 mm"]
    assert any(not v.valid and v.rule == "advisor" for v in enforced.verdicts) and "refused again" in enforced.note


def test_the_cut_is_judged_by_every_rule_on_the_lidar():
    # lidar_clearance refuses 399 mm into a wall 600 mm ahead and says 350 mm is safe; the cut passes
    world, _, steps = run([answer(straight(399))], validators=["command_limits", "lidar_clearance"], wall_mm=600)
    assert [s.describe() for s in world.executed] == ["straight forward 350 mm"]
    assert {v.rule for v in steps[0].enforced.verdicts} == {"command_limits", "lidar_clearance"}


def test_an_answer_that_did_not_parse_is_never_enforced():
    # the last attempt does not parse: the one before it (parsed, refused) is cut
    defences = ENFORCE.model_copy(update={"failure_threshold": 1})
    world, _, steps = run([answer(straight(300)), "straight 900 please"], {"max_mm": 100, "safe_mm": 100},
                          defences=defences)
    assert steps[0].attempts[1].parse_error is not None and steps[0].enforced.attempt == 0
    assert [s.describe() for s in world.executed] == ["straight forward 100 mm"]
    # no answer parsed at all: nothing is cut, the step holds
    world, result, steps = run(["not json", '{"control": "forward 9000"}'], {"max_mm": 100, "safe_mm": 100},
                               defences=defences)
    assert world.executed == [] and steps[0].enforced.attempt is None and not steps[0].enforced.ran
    assert result.outcome == Outcome.TIMEOUT


def test_an_accepted_answer_is_never_enforced_and_abort_and_hold_are_unchanged():
    world, _, steps = run([answer(straight(50))], {"max_mm": 100, "safe_mm": 100})
    assert steps[0].accepted and steps[0].enforced is None
    for mode, outcome in (("abort", Outcome.SAFE_ABORT), ("hold", Outcome.TIMEOUT)):
        world, result, steps = run([answer(straight(300))], {"max_mm": 100, "safe_mm": 100},
                                   defences=ENFORCE.model_copy(update={"on_exhausted": mode}))
        assert world.executed == [] and result.outcome == outcome and steps[0].enforced is None


def test_the_next_prompt_says_the_rules_cut_ran():
    world, _, steps = run([answer(straight(300))], {"max_mm": 100, "safe_mm": 100}, max_steps=2)
    reference = steps[0].to_reference()
    assert "rules' cut of attempt 1 ran" in reference.outcome_note and reference.planning == "plan"
    assert [e.signal.describe() for e in reference.executed] == ["straight forward 100 mm"]


def test_cut_plan_without_any_usable_advice_keeps_only_the_signals_before():
    plan = [Turn(command="turn", direction="left", angle=10.0), Straight(command="straight", direction="forward",
                                                                          distance=300.0)]
    refused = Verdict(rule="r", valid=False, reason="no", signal_index=1)
    assert cut_plan(plan, [refused])[0] == plan[:1]
    plan_level = Verdict(rule="r", valid=False, reason="no")  # about no signal: nothing is kept
    assert cut_plan(plan, [plan_level])[0] == []
    wrong_kind = refused.model_copy(update={"advice": Advice(safe_deg=5)})  # degrees for a straight: dropped
    assert cut_plan(plan, [wrong_kind])[0] == plan[:1]


def test_a_trial_with_enforced_steps_replays_identically():
    import pytest

    from safeembodai_core.loop.replay import ReplayDiverged, replay_trial
    from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
    from safeembodai_core.testing import inline_plugins, tiny_scenario

    plugins = inline_plugins()
    arm = {"safety_validation": True, "failure_threshold": 0, "on_exhausted": "enforce",
           "validators": ["command_limits", "lidar_clearance"]}
    scenario = tiny_scenario([answer(straight(399))], arm=arm, max_steps=8, registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, scenario.environments[0].key, "arm", "condition", 0)
        runner.run(spec)
        records = runner.state.steps(spec.trial_id)
        ran = [r for r in records if r.enforced is not None and r.enforced.ran]
        assert ran and all(r.executed and not r.accepted for r in ran)  # the world met the cut
        _, replayed, _ = replay_trial(runner, spec, records)
        assert [r.enforced for r in replayed] == [r.enforced for r in records]
        assert [r.executed for r in replayed] == [r.executed for r in records]
        # a record whose cut differs is caught
        forged = [r.model_copy(update={"enforced": None}) if r is ran[0] else r for r in records]
        with pytest.raises(ReplayDiverged, match="rules' cut differs"):
            replay_trial(runner, spec, forged)
    finally:
        runner.close()
