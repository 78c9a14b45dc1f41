"""A trial ends cleanly whatever a component or an answer does; nothing secret or forged gets recorded."""

from __future__ import annotations

import types

import pytest

from safeembodai_core import BackendError, hookimpl, run_guarded_trial
from safeembodai_core.contracts.components import Attacker, BackendReply, LLMBackend, Validator
from safeembodai_core.loop import Defences
from safeembodai_core.models import GroundTruth, Outcome, ResponseParseError, parse_response
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.testing import CorridorWorld, ReplayBackend, answer, straight, turn

GUARDED = Defences(security_prefix=True, state_management=True, safety_validation=True)


def test_deeply_nested_json_is_a_refusal_not_a_crash():
    hostile = '{"control": ' + "[" * 30_000 + "]" * 30_000 + "}"
    with pytest.raises(ResponseParseError, match="too deeply"):
        parse_response(hostile)
    world = CorridorWorld()
    result, steps = run_guarded_trial(world, ReplayBackend(hostile, answer(turn(10))), defences=GUARDED, max_steps=1)
    assert result.outcome != Outcome.ERROR and steps[0].attempts[0].parse_error and steps[0].accepted


def test_a_validator_that_raises_refuses_instead_of_ending_the_trial():
    class Broken(Validator):
        def validate(self, signal, context):
            return {}["missing"]

    class NotAVerdict(Validator):
        def validate(self, signal, context):
            return True

    from safeembodai_core.models import Straight
    from safeembodai_core.validation.context import ValidationContext, validate_plan

    signal = Straight(command="straight", direction="forward", distance=100)
    verdicts = validate_plan([signal], ValidationContext(None), [("broken", Broken()), ("odd", NotAVerdict())])
    assert [v.valid for v in verdicts] == [False, False]
    assert "KeyError" in verdicts[0].reason and "not a Verdict" in verdicts[1].reason


def test_after_trial_hook_failure_keeps_the_result():
    plugin = types.ModuleType("flaky_exporter")
    plugin.after_trial = hookimpl(lambda spec, result: (_ for _ in ()).throw(RuntimeError("exporter down")))
    result, _ = run_guarded_trial(CorridorWorld(), ReplayBackend(answer(turn(10))), defences=GUARDED, max_steps=2,
                                  plugins=load_plugins([plugin], environ={}))
    assert result.outcome == Outcome.TIMEOUT


def test_unbuildable_components_end_that_trial_as_error_and_the_run_goes_on(tmp_path):
    from pydantic import BaseModel, ConfigDict

    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.errors import ComponentError
    from safeembodai_core.testing import tiny_scenario

    class Empty(BaseModel):
        model_config = ConfigDict(extra="forbid")

    def factory(options, context):
        if context.seed % 2:
            raise ComponentError("the device for this seed is offline")
        return ReplayBackend(answer(turn(10)))

    plugin = types.ModuleType("moody")
    plugin.register_llm_backends = hookimpl(lambda register: register("moody", factory, options=Empty))
    plugins = load_plugins([plugin], environ={})
    scenario = tiny_scenario(registry=plugins.registry, trials=4, max_steps=1, backend="moody")
    ablation = Ablation(scenario, plugins, RunFolder(tmp_path / "run"))
    try:
        results = ablation.run()
    finally:
        ablation.close()
    outcomes = {r.spec.index: r.outcome for r in results}
    assert len(outcomes) == 4 and Outcome.ERROR in outcomes.values() and Outcome.TIMEOUT in outcomes.values()
    errored = next(r for r in results if r.outcome == Outcome.ERROR)
    assert "device for this seed is offline" in errored.detail


def test_secrets_do_not_reach_logs_or_trial_details(capfd):
    class Leaky(LLMBackend):
        def complete(self, prompt, rng):
            kwargs = {"api_key": "sk-proj-SECRETSECRETSECRET"}  # noqa: F841  (a local a traceback could show)
            raise TypeError("bad call with Bearer sk-live-ABCDEFGHIJKLMNOP")

    result, _ = run_guarded_trial(CorridorWorld(), Leaky(), defences=GUARDED, max_steps=1)
    captured = capfd.readouterr()
    assert result.outcome == Outcome.ERROR
    for secret in ("SECRETSECRET", "ABCDEFGHIJKLMNOP"):
        assert secret not in result.detail and secret not in captured.err and secret not in captured.out


def test_attackers_cannot_rewrite_ground_truth():
    class Liar(Attacker):
        def attack(self, target):
            target.observation.truth = GroundTruth(target_in_view=False)
            return []

    world = CorridorWorld()  # the target is always in view there
    result, steps = run_guarded_trial(world, ReplayBackend(answer(turn(10))), defences=GUARDED, max_steps=2,
                                      attackers=[Liar()])
    assert all(step.truth.target_in_view for step in steps) and result.target_visible_steps == 2


def test_attack_detection_counts_the_first_parsed_answer_only():
    class Insists(LLMBackend):
        def __init__(self):
            self.calls = 0

        def complete(self, prompt, rng):
            self.calls += 1
            first = self.calls == 1
            return BackendReply(text=answer(straight(399) if first else turn(10), is_attack=not first))

    _, steps = run_guarded_trial(CorridorWorld(wall_mm=600), Insists(), defences=GUARDED, max_steps=1)
    assert len(steps[0].attempts) == 2 and steps[0].attempts[1].response.flags_attack
    assert not steps[0].flagged_attack  # the retry's flag does not count


def test_backend_error_detail_is_kept():
    class Down(LLMBackend):
        def complete(self, prompt, rng):
            raise BackendError("503 from the provider after 4 tries")

    result, _ = run_guarded_trial(CorridorWorld(), Down(), defences=GUARDED, max_steps=1)
    assert result.outcome == Outcome.ERROR and "503" in result.detail
