"""The simulated pilot reads refusals as data, never their words: the same trials with every
refusal reason reworded give the same plans, verdicts and motions (a reworded reason must not
change the pilot, so a rule's wording is free to improve)."""

from __future__ import annotations

import pytest

import safeembodai_core.loop.guarded_step as guarded_step
from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
from safeembodai_core.scenario import load_scenario
from safeembodai_core.testing import inline_plugins, tiny_scenario

CARELESS = {"use": "mock", "options": {"ignore_clearance_p": 0.9, "feedback_compliance_p": 1.0, "retry": "amend"}}


def _reworded(monkeypatch):
    judge = guarded_step.validate_plan

    def reworded(plan, context, validators):
        return [v if v.valid else v.model_copy(update={"reason": "refused: no words to read here"})
                for v in judge(plan, context, validators)]

    monkeypatch.setattr(guarded_step, "validate_plan", reworded)


def _what_happened(scenario, plugins, cells):
    """Per trial and step: every attempt's plan and verdicts (valid, rule, signal, advice), and what ran."""
    runner = ScenarioRunner(scenario, plugins)
    seen = []
    try:
        for environment, arm, condition, index in cells:
            spec = trial_spec(scenario, environment, arm, condition, index)
            result = runner.run(spec)
            for record in runner.state.steps(spec.trial_id):
                seen.append((spec.trial_id, record.step, [
                    (a.response.control if a.response else None, a.parse_error is None,
                     [(v.valid, v.rule, v.signal_index, v.advice) for v in a.verdicts]) for a in record.attempts],
                    [item.signal for item in record.executed]))
            seen.append((spec.trial_id, result.outcome, result.steps))
    finally:
        runner.close()
    return seen


def _advised(seen):
    return sum(1 for entry in seen if len(entry) == 4 for _, _, verdicts in entry[2] for v in verdicts
               if v[3] is not None)


def test_flatland_trials_are_the_same_with_every_reason_reworded(monkeypatch):
    plugins = inline_plugins()
    scenario = tiny_scenario(environment={"use": "flatland", "options": {"obstacles": 4}}, max_steps=8, trials=3,
                             backend=CARELESS, registry=plugins.registry,
                             arm={"safety_validation": True, "validators": ["lidar_clearance"]})
    cells = [("flatland", "arm", "condition", index) for index in range(3)]
    plain = _what_happened(scenario, plugins, cells)
    assert _advised(plain) >= 3  # refusals with advice happened, so the pilot had something to read
    _reworded(monkeypatch)
    assert _what_happened(scenario, plugins, cells) == plain


@pytest.mark.slow
def test_moving_obstacle_trials_are_the_same_with_every_reason_reworded(repo, monkeypatch):
    """DO with Labbots and the shipped moving-obstacle arm: waits and step-asides are read as data too."""
    plugins = inline_plugins()
    scenario = load_scenario(repo / "scenarios" / "dynamic.yaml", ["trials=3", "state=memory"], plugins.registry)
    cells = [(scenario.environments[0].key, "moving", "no_attack", index) for index in range(3)]
    plain = _what_happened(scenario, plugins, cells)
    assert _advised(plain) >= 1
    _reworded(monkeypatch)
    assert _what_happened(scenario, plugins, cells) == plain
