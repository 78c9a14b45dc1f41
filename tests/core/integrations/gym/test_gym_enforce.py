"""``on_exhausted: enforce`` under the Gymnasium guard: the loop's trial, its answers replayed into the
guarded env, gives the same verdicts, the same rules' cut (or hold) and the same motions."""

from __future__ import annotations

import pytest

gymnasium = pytest.importorskip("gymnasium", reason='pip install -e ".[gym]"')

from safeembodai_core.gym import SafeEmbodAIEnv, SafeEmbodAIGuard  # noqa: E402
from safeembodai_core.runs.runner import ScenarioRunner, trial_spec  # noqa: E402
from safeembodai_core.scenario import load_scenario  # noqa: E402
from safeembodai_core.testing import answer, inline_plugins, straight, tiny_scenario, turn  # noqa: E402


def _loop_then_guard(scenario, plugins, environment, arm, condition, index):
    """The loop's trial ``index``; then its answers, attempt by attempt, into the guarded env: each step's
    info next to its record."""
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, environment, arm, condition, index)
        result = runner.run(spec)
        steps = runner.state.steps(spec.trial_id)
    finally:
        runner.close()
    env = SafeEmbodAIGuard(SafeEmbodAIEnv(environment, scenario=scenario, environment=environment, arm=arm,
                                          condition=condition, action_format="text", plugins=plugins))
    met = []
    try:
        env.reset(options={"index": index})
        for record in steps:
            for attempt in record.attempts:
                _, _, terminated, truncated, info = env.step(attempt.raw_text)
                assert info["refused"] == (not attempt.accepted), (record.step, attempt.index)
                if not attempt.accepted:
                    assert info["reasons"] == attempt.failures(), (record.step, attempt.index)
            met.append((record, info))
    finally:
        env.close()
    return result, met


def _same(record, info):
    if record.enforced is None:
        assert info["enforced"] is None, record.step
    else:
        assert info["enforced"] == record.enforced.model_dump(mode="json"), record.step
    assert info["executed"] == [e.model_dump(mode="json") for e in record.executed], record.step
    assert info["pose"] == record.pose_after.model_dump(), record.step


def test_the_guard_runs_the_loops_cut_or_holds_as_the_loop_does():
    plugins = inline_plugins()
    arm = {"safety_validation": True, "failure_threshold": 1, "on_exhausted": "enforce",
           "validators": ["command_limits", {"use": "lidar_clearance", "options": {"safety_distance_mm": 1200}}]}
    replies = [answer(turn(20), straight(399)), "not json", answer(straight(399)), answer(straight(399)),
               answer(straight(399)), "not json", answer(turn(60)), answer(straight(399), turn(30))]
    scenario = tiny_scenario(replies, arm=arm, max_steps=10, registry=plugins.registry)
    result, met = _loop_then_guard(scenario, plugins, scenario.environments[0].key, "arm", "condition", 0)
    enforced = [record for record, _ in met if record.enforced is not None]
    assert any(r.enforced.ran for r in enforced) and any(not r.enforced.ran for r in enforced)
    assert any(r.attempts[-1].parse_error is not None and r.enforced.ran for r in enforced)  # the one before cut
    for record, info in met:
        _same(record, info)


@pytest.mark.slow
def test_a_fresh_scan_enforce_arm_in_do_gets_the_loops_cuts_under_the_guard(repo):
    """movers.yaml's ``moving`` arm with ``on_exhausted: enforce``, the mock pilot ignoring advice, in DO
    (tuning family): every attempt's verdict, every cut and every motion as in the loop's trial."""
    plugins = inline_plugins()
    scenario = load_scenario(repo / "scenarios" / "movers.yaml", [
        "trials=4", "state=memory", "max_steps=12", "arms.moving.on_exhausted=enforce",
        "arms.moving.failure_threshold=1", "backend.options.feedback_compliance_p=0",
        "environments.0.options.labbot_family=tuning"], plugins.registry)
    result, met = _loop_then_guard(scenario, plugins, "DO", "moving", "no_attack", 2)  # trial 2: two cuts ran
    assert sum(record.enforced is not None and record.enforced.ran for record, _ in met) == 2
    for record, info in met:
        _same(record, info)
