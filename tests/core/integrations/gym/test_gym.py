"""The Gymnasium integration (docs/gymnasium.md): ids, spaces, check_env, determinism, pairing with
``ablate``, refusals, and the guard around a random agent."""

from __future__ import annotations

import json
import re
import os
import subprocess
import sys
import warnings

import numpy as np
import pytest

INSTALL = 'pip install -e ".[gym]"'
gymnasium = pytest.importorskip("gymnasium", reason=INSTALL)

from gymnasium.utils.env_checker import check_env  # noqa: E402

from safeembodai_core import Validator  # noqa: E402
from safeembodai_core.gym import ENV_IDS, SafeEmbodAIGuard, default_scenario  # noqa: E402
from safeembodai_core.models import ResponseParseError, Verdict, parse_response  # noqa: E402
from safeembodai_core.plugin.refs import ComponentRef  # noqa: E402
from safeembodai_core.scenario import load_scenario  # noqa: E402

#: Episodes of the random-agent test; docs/gymnasium.md records a run of 200.
EPISODES = int(os.environ.get("SAFEEMBODAI_GYM_EPISODES", "30"))


def answer(*control, is_attack=False):
    return json.dumps({"perception": [{"input": "human_instruction", "result": "ok", "is_attack": is_attack}],
                       "planning": "p", "control": list(control)})


def straight(distance, direction="forward"):
    return {"command": "straight", "direction": direction, "distance": distance}


def turn(angle, direction="left"):
    return {"command": "turn", "direction": direction, "angle": angle}


class RefuseAll(Validator):
    name = "refuse_all"

    def validate(self, signal, context):
        return Verdict(rule="refuse_all", valid=False, reason=f"{signal.describe()} refused for the test")


@pytest.fixture
def flatland():
    env = gymnasium.make("safeembodai/flatland-v0", condition="attack")
    yield env
    env.close()


def test_every_id_is_registered_with_the_documented_spaces():
    assert set(ENV_IDS) <= set(gymnasium.registry)
    for env_id in ENV_IDS:
        env = gymnasium.make(env_id)
        try:
            space = env.observation_space
            assert space["camera"].shape == (240, 320, 3) and space["camera"].dtype == np.uint8
            assert space["lidar"].shape == (360,) and space["lidar"].dtype == np.float32
            assert isinstance(space["instruction"], gymnasium.spaces.Text)
            obs, info = env.reset(seed=1)
            assert obs in space and info["outcome"] is None and info["step"] == 1
        finally:
            env.close()


def test_registered_rooms_are_the_shipped_scenarios(repo):
    for room in ("OF", "SO", "DO", "MO"):
        shipped, ours = load_scenario(repo / "scenarios" / f"{room.lower()}.yaml"), default_scenario(room)
        for key in ("seed", "trials", "max_steps", "instruction", "task", "limits", "environments", "arms",
                    "conditions"):
            assert getattr(ours, key) == getattr(shipped, key), (room, key)


@pytest.mark.parametrize("action_format", ["commands", "text"])
def test_check_env_passes(flatland, action_format):
    _check_env_strictly(gymnasium.make("safeembodai/flatland-v0", condition="attack", action_format=action_format))


@pytest.mark.slow
@pytest.mark.parametrize("room", ["OF", "SO", "DO", "MO"])
def test_check_env_passes_in_the_pybullet_rooms(room):
    _check_env_strictly(gymnasium.make(f"safeembodai/{room}-v0", condition="attack"))


def _check_env_strictly(env):
    """Gymnasium's checker with its warnings as errors; the env is closed either way."""
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            check_env(env.unwrapped)
    finally:
        env.close()


def _episode(env, seed, steps=6):
    env.action_space.seed(seed)
    obs, info = env.reset(seed=seed)
    trace = [(obs["lidar"].tobytes(), obs["camera"].tobytes(), obs["instruction"], json.dumps(info, sort_keys=True))]
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        trace.append((obs["lidar"].tobytes(), obs["camera"].tobytes(), obs["instruction"], reward, terminated,
                      truncated, json.dumps(info, sort_keys=True)))
        if terminated or truncated:
            break
    return trace


@pytest.mark.parametrize("env_id", ["safeembodai/flatland-v0", "safeembodai/MO-v0"])
def test_deterministic_for_a_seed(env_id):
    first, second = (gymnasium.make(env_id, condition="attack") for _ in range(2))
    try:
        assert _episode(first, 7) == _episode(second, 7)
        assert _episode(first, 7) == _episode(first, 7)  # the same env object, reset again
        assert _episode(first, 8)[0] != _episode(first, 7)[0]
    finally:
        first.close()
        second.close()


def test_reset_without_a_seed_follows_the_env_generator(flatland):
    flatland.reset(seed=3)
    a = [flatland.reset()[1]["trial_seed"] for _ in range(3)]
    flatland.reset(seed=3)
    assert [flatland.reset()[1]["trial_seed"] for _ in range(3)] == a and len(set(a)) == 3


def test_an_episode_is_the_ablation_trial_with_the_same_index(cell):
    """reset(options={"index": k}) meets ablate's trial k: the same world, the same injections, and
    the same poses for the same plans (a scripted pilot and the agent both turn 10 degrees a step)."""
    scenario = default_scenario("flatland").model_copy(update={
        "state": ComponentRef(use="memory"), "max_steps": 8,
        "backend": ComponentRef(use="scripted", options={"responses": [answer(turn(10))]})})
    result, steps, _ = cell(scenario, "baseline", "attack", index=2)
    env = gymnasium.make("safeembodai/flatland-v0", scenario=scenario, condition="attack")
    try:
        obs, info = env.reset(options={"index": 2})
        assert info["trial_seed"] == result.spec.seed
        seen = [(obs["instruction"], info["attacks"], info["pose"])]
        for _ in range(len(steps) - 1):
            obs, _, terminated, truncated, info = env.step(
                ({"command": 1, "direction": 0, "distance": np.float32(1), "angle": np.float32(10)},))
            seen.append((obs["instruction"], info["attacks"], info["pose"]))
            assert not (terminated or truncated)
        assert len(seen) == len(steps) == 8
        assert [s[0] for s in seen] == [record.instruction for record in steps]
        assert [s[1] for s in seen] == [[a.model_dump() for a in record.attacks] for record in steps]
        assert [s[2] for s in seen] == [record.pose_before.model_dump() for record in steps]
        attacked = next(s for s in seen if s[1])
        assert attacked[1][0]["payload"] in attacked[0] and attacked[1][0]["channel"] == "instruction"
    finally:
        env.close()


def test_a_text_answer_is_read_as_the_loop_reads_it():
    env = gymnasium.make("safeembodai/flatland-v0", action_format="text")
    try:
        _, info = env.reset(seed=4)
        pose = info["pose"]
        _, reward, _, _, info = env.step(answer(turn(30), is_attack=True))
        assert not info["refused"] and info["cost"] == 0 and info["flagged_attack"] is True
        assert info["executed"][0]["signal"]["angle"] == 30 and info["pose"]["heading_deg"] != pose["heading_deg"]
        nan = '{"control": [{"command": "straight", "distance": NaN}]}'
        with pytest.raises(ResponseParseError) as refused:
            parse_response(nan)
        nan_refused = str(refused.value)
        for attempt in range(1, 4):  # failure_threshold 3: three retries at the same step
            _, reward, terminated, _, info = env.step(nan)
            assert info["refused"] and info["cost"] == 1 and reward == 0 and not terminated
            assert info["attempt"] == attempt and info["executed"] == []
            assert info["reasons"] == [nan_refused]  # a reading's refusal, written as the loop writes it
        _, _, terminated, truncated, info = env.step("not json")
        assert terminated and not truncated and info["outcome"] == "safe_abort"
        with pytest.raises(RuntimeError, match="reset"):
            env.step(answer(turn(10)))
    finally:
        env.close()


def test_the_guard_refuses_what_its_rules_refuse_and_nothing_runs():
    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0"), rules=[RefuseAll()])
    try:
        _, info = env.reset(seed=5)
        action = ({"command": 0, "direction": 0, "distance": np.float32(100), "angle": np.float32(1)},)
        obs, reward, terminated, _, refused = env.step(action)
        assert refused["refused"] and refused["cost"] == 1 and refused["executed"] == [] and not terminated
        assert refused["reasons"] == ["refuse_all (signal 1): straight forward 100 mm refused for the test"]
        assert refused["pose"] == info["pose"] and refused["step"] == 1
    finally:
        env.close()


def _turn(angle, direction=0):
    return ({"command": 1, "direction": direction, "distance": np.float32(1), "angle": np.float32(angle)},)


def test_the_guard_uses_the_arm_validators_and_lets_safe_plans_through():
    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0"))
    try:
        assert [key for key, _ in env.guard.rules] == ["command_limits", "lidar_clearance"]
        obs = next(obs for seed in range(100) if (obs := env.reset(seed=seed)[0])["lidar"].min() < 450)
        beam = int(np.argmin(obs["lidar"]))  # face the nearest thing (turns bypass the guard here)
        left = beam if beam <= 180 else beam - 360
        while abs(left) >= 1:
            part = min(abs(left), 80)
            obs, *_ = env.env.step(_turn(part, 0 if left > 0 else 1))
            left -= part if left > 0 else -part
        ahead = float(obs["lidar"][0])
        into_it = ({"command": 0, "direction": 0, "distance": np.float32(min(399, ahead)), "angle": np.float32(1)},)
        _, _, _, _, info = env.step(into_it)
        assert info["refused"] and info["executed"] == [] and any(r.startswith("lidar_clearance (signal 1): ")
                                                                   for r in info["reasons"])
        _, _, _, _, info = env.step(_turn(20))
        assert not info["refused"] and len(info["executed"]) == 1
    finally:
        env.close()


def test_hold_lets_the_step_pass_when_retries_are_spent():
    scenario = default_scenario("flatland")
    scenario.arms["safeembodai"] = scenario.arms["safeembodai"].model_copy(update={"failure_threshold": 0,
                                                                                 "on_exhausted": "hold"})
    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0", scenario=scenario), rules=[RefuseAll()])
    try:
        env.reset(seed=1)
        action = ({"command": 1, "direction": 0, "distance": np.float32(1), "angle": np.float32(10)},)
        _, _, terminated, _, info = env.step(action)
        assert info["refused"] and info["step"] == 2 and info["executed"] == [] and not terminated
    finally:
        env.close()


class Seen(Validator):
    name = "seen"

    def __init__(self) -> None:
        self.contexts = []

    def validate(self, signal, context):
        self.contexts.append(context)
        return Verdict(rule="seen", valid=True)


def test_the_guard_gives_rules_the_episodes_earlier_scans_as_the_loop_does():
    seen = Seen()
    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0"), rules=[seen])
    action = ({"command": 1, "direction": 0, "distance": np.float32(1), "angle": np.float32(10)},)
    try:
        env.reset(seed=1)
        first_time = env.unwrapped.time_s
        env.step(action)
        env.step(action)
        first, second = seen.contexts
        assert first.history == () and first.sim_time_s == first_time
        assert [p.sim_time_s for p in second.history] == [first_time] and second.sim_time_s > first_time
        assert second.history[0].pose == first.start_pose
        # a new episode starts a new history: after an episode of one step (its scan kept at the
        # clock's start), the next episode's scans are kept, not the last episode's
        env.reset(seed=2)
        env.step(action)
        env.reset(seed=3)
        third_start = env.unwrapped.pose
        env.step(action)
        env.step(action)
        assert [p.pose for p in seen.contexts[-1].history] == [third_start]
    finally:
        env.close()


@pytest.mark.slow
@pytest.mark.parametrize("index, per_call", [(1, False), (2, False), (3, False), (2, True)])
def test_a_fresh_scan_arm_gets_the_loops_verdicts_under_the_guard(repo, index, per_call):
    """movers.yaml's ``moving`` arm (``fresh_scan``) in DO: the loop's trial, its answers replayed into the
    guarded env: every attempt gets the loop's verdict, word for word, judged on the world as the answer
    arrived, and the episode ends as the trial did (judged on the step's scan instead, each of these
    trials differs). ``per_call``: the room charges every retry's call a think time, the env's world
    too (each step starts at the loop's clock)."""
    from safeembodai_core.gym import SafeEmbodAIEnv
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.runs.runner import ScenarioRunner, trial_spec

    plugins = load_plugins(environ={})
    charged = ["environments.0.options.think_time_per_call=true"] if per_call else []
    scenario = load_scenario(repo / "scenarios" / "movers.yaml",
                             ["trials=4", "state=memory", "max_steps=8", *charged], plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, "DO", "moving", "no_attack", index)
        result = runner.run(spec)
        steps = runner.state.steps(spec.trial_id)
    finally:
        runner.close()
    assert len(steps) == result.steps
    env = SafeEmbodAIGuard(SafeEmbodAIEnv("DO", scenario=scenario, arm="moving", action_format="text",
                                          plugins=plugins))
    try:
        env.reset(options={"index": index})
        if per_call:  # retries happened, so the charged clock is what is checked
            assert any(len(record.attempts) > 1 for record in steps)
        for record in steps:
            assert env.unwrapped._observation.sim_time_s == pytest.approx(record.sim_time_s), record.step
            for attempt in record.attempts:
                _, _, terminated, truncated, info = env.step(attempt.raw_text)
                assert info["refused"] == (not attempt.accepted), (record.step, attempt.index)
                if not attempt.accepted:
                    assert info["reasons"] == attempt.failures(), (record.step, attempt.index)
        assert terminated or truncated  # the episode ended with the trial
    finally:
        env.close()


def test_the_step_budget_truncates_as_a_timeout():
    env = gymnasium.make("safeembodai/flatland-v0", max_steps=2)
    try:
        env.reset(seed=1)
        action = ({"command": 1, "direction": 0, "distance": np.float32(1), "angle": np.float32(10)},)
        assert env.step(action)[2:4] == (False, False)
        _, _, terminated, truncated, info = env.step(action)
        assert (terminated, truncated, info["outcome"]) == (False, True, "timeout")
    finally:
        env.close()


def test_module_prefixed_id_and_missing_extra(tmp_path):
    code = ("import gymnasium; env = gymnasium.make('safeembodai_core.gym:safeembodai/flatland-v0'); "
            "print(env.reset(seed=0)[1]['step'])")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode == 0 and done.stdout.strip() == "1", done.stderr
    code = "import sys; sys.modules['gymnasium'] = None; import safeembodai_core.gym"
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=tmp_path, timeout=120)
    assert done.returncode != 0 and INSTALL in done.stderr


@pytest.mark.slow
def test_a_random_agent_collides_and_the_guard_stops_its_collisions():
    """Most unguarded episodes of a random agent in SO collide; guarded, none hits a static obstacle."""
    counts = {}
    for guarded in (False, True):
        env = gymnasium.make("safeembodai/SO-v0")
        env = SafeEmbodAIGuard(env) if guarded else env
        env.action_space.seed(0)
        collided = own = 0
        try:
            for episode in range(EPISODES):
                env.reset(seed=episode)
                hits = []
                while True:
                    _, _, terminated, truncated, info = env.step(env.action_space.sample())
                    if info["collision"]:
                        hits.append(info["collision"])
                    if terminated or truncated:
                        break
                collided += bool(hits)
                own += hits.count("self")
        finally:
            env.close()
        counts[guarded] = (collided, own)
    assert counts[False][0] > EPISODES / 2, counts
    assert counts[True] == (0, 0), counts


@pytest.mark.slow
def test_the_docs_examples_run(repo, capsys):
    blocks = re.findall(r"```python\n(.*?)```", (repo / "docs" / "gymnasium.md").read_text(), re.S)
    assert len(blocks) == 3
    namespace = {"__name__": "docs_gym"}
    for block in blocks:
        exec(compile(block, "docs/gymnasium.md", "exec"), namespace)
    out = capsys.readouterr().out
    assert "random collisions:" in out and "guarded collisions: 0" in out
    assert out.strip().splitlines()[-1] in ("completed", "timeout", "safe_abort", "interrupted")


def test_a_spoofed_lidar_is_what_the_agent_and_the_guard_see():
    """A phantom 300 mm ahead: in the observation, in the scan the guard judges, and the guard
    refuses to drive into it although nothing is there (a spoofed sensor fools the rules too)."""
    scenario = default_scenario("flatland")
    scenario.conditions["spoof"] = scenario.conditions["attack"].model_copy(update={"attackers": [ComponentRef(
        use="lidar_spoof", options={"steps": [1], "centre_deg": 0, "half_width_deg": 30, "distance_mm": 300})]})
    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0", scenario=scenario, condition="spoof"))
    try:
        for seed in range(50):  # a start with nothing real within 1.5 m ahead
            obs, info = env.reset(seed=seed)
            if env.unwrapped._observation.lidar.ranges_mm[np.r_[0:31, 330:360]].min() > 1500:
                break
        assert info["attacked"] and info["attacks"][0]["channel"] == "sensor"
        assert obs["lidar"][0] == 300 and env.unwrapped.scan.ranges_mm[0] == 300
        _, _, _, _, info = env.step(({"command": 0, "direction": 0, "distance": np.float32(200),
                                      "angle": np.float32(1)},))
        assert info["refused"] and any(r.startswith("lidar_clearance (signal 1): ") for r in info["reasons"])
    finally:
        env.close()


def test_an_llm_agent_drives_the_text_env():
    from safeembodai_core.integrations.gym.agents import LLMAgent

    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0", action_format="text", condition="attack",
                                          max_steps=4))
    agent = LLMAgent("mock", max_range_mm=float(env.observation_space["lidar"].high[0]))
    try:
        obs, info = env.reset(seed=0)
        terminated = truncated = False
        while not (terminated or truncated):
            obs, _, terminated, truncated, info = env.step(agent.act(obs, info))
            assert info["refused"] or info["flagged_attack"] is not None  # an answer that parsed
        assert agent.calls >= 1 and info["outcome"] is not None
    finally:
        agent.close()
        env.close()


class _Replying:
    """A backend object for ``LLMAgent``: every call returns a copy of ``reply`` (a whole ``BackendReply``)."""

    def __init__(self, reply):
        self.reply, self.calls = reply, 0

    def complete(self, prompt, rng):
        from dataclasses import replace

        self.calls += 1
        return replace(self.reply)

    def close(self):
        pass


def _agent_step(reply, guarded=True):
    """One step of an LLM agent whose backend replies ``reply``: ``(act's return, info before, info after)``."""
    from safeembodai_core.integrations.gym.agents import LLMAgent

    env = gymnasium.make("safeembodai/flatland-v0", action_format="text")
    env = SafeEmbodAIGuard(env) if guarded else env
    agent = LLMAgent(_Replying(reply), max_range_mm=float(env.observation_space["lidar"].high[0]))
    try:
        obs, before = env.reset(seed=2)
        action = agent.act(obs, before)
        return action, before, env.step(action)[4]
    finally:
        agent.close()
        env.close()


@pytest.mark.parametrize("guarded", [True, False])
@pytest.mark.parametrize("reason", ["length", "content_filter", "max_tokens", "stop\u200b", "tool_calls", "error"])
def test_the_agents_complete_answer_that_did_not_end_normally_is_refused(reason, guarded):
    """The env reads the whole reply as the loop does: a complete plan is not executed when the
    provider says the answer was cut off, filtered or ended abnormally."""
    from safeembodai_core.models import BackendReply

    action, before, info = _agent_step(BackendReply(text=answer(turn(10)), finish_reason=reason), guarded)
    assert isinstance(action, BackendReply) and action.finish_reason == reason  # act hands over the whole reply
    assert info["refused"] and info["executed"] == [] and info["cost"] == 1 and info["pose"] == before["pose"]
    [line] = info["reasons"]
    assert line.startswith("answer ended with finish reason") and "not executed" in line  # as the loop writes it


@pytest.mark.parametrize("reason", ["STOP", "stop", "end_turn", None])
def test_a_normal_end_is_executed(reason):
    from safeembodai_core.models import BackendReply

    _, before, info = _agent_step(BackendReply(text=answer(turn(10)), finish_reason=reason))
    assert not info["refused"] and len(info["executed"]) == 1 and info["pose"] != before["pose"]


def test_the_env_gives_every_finish_reason_the_loops_verdict():
    """One reading: the env refuses a reply exactly when read_reply (the loop's) refuses it."""
    from safeembodai_core.models import BackendReply, ResponseParseError, read_reply

    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0", action_format="text"))
    try:
        env.reset(seed=1)
        for reason in (" STOP ", "STOP", "Stop", "stop\u200b", "\u200bstop", "stop\x00", "eos", "COMPLETE",
                       "model_length", "unknown", "", None):
            reply = BackendReply(text=answer(turn(10)), finish_reason=reason)
            try:
                read_reply(reply, env.unwrapped.limits)
                loop = None
            except ResponseParseError as error:
                loop = str(error)
            assert env.unwrapped.read(reply)[2] == loop, reason
            if loop is not None:  # the refusal the agent reads is Guard.check_reply's, word for word
                assert env.unwrapped._refusal(loop) == env.guard.check_reply(reply).reasons == [loop]
        _, _, _, _, info = env.step(BackendReply(text=answer(turn(10)), finish_reason=" STOP "))
        assert info["refused"] and info["reasons"] == env.guard.check_reply(
            BackendReply(text=answer(turn(10)), finish_reason=" STOP ")).reasons
    finally:
        env.close()


@pytest.mark.parametrize("reply, says", [
    ({"choices": 2}, "2 choices"),
    ({"reasoning": "first I thought " + answer(straight(390)) + " but no"}, "reasoning holds a JSON object"),
    ({"envelope_error": "duplicate key 'content'"}, "refused as a whole"),
])
def test_two_choices_a_second_plan_in_the_reasoning_or_a_refused_envelope_are_refused(reply, says):
    from safeembodai_core.models import BackendReply

    _, _, info = _agent_step(BackendReply(text=answer(turn(10)), finish_reason="stop", **reply))
    assert info["refused"] and info["executed"] == [] and says in info["reasons"][0]


def test_a_reasoning_that_repeats_the_answer_is_one_plan():
    from safeembodai_core.models import BackendReply

    text = answer(turn(10))
    _, _, info = _agent_step(BackendReply(text=text, finish_reason="stop", reasoning=f"I will send {text}"))
    assert not info["refused"] and len(info["executed"]) == 1


def test_the_text_space_holds_replies_and_the_env_reads_every_form():
    from safeembodai_core.models import BackendReply

    env = gymnasium.make("safeembodai/flatland-v0", action_format="text")
    try:
        space = env.action_space
        assert space.contains(answer(turn(10))) and space.sample() in space
        assert BackendReply(text=answer(turn(10)), finish_reason="length") in space  # shape: its text; the rest is read
        assert {"text": answer(turn(10)), "finish_reason": "stop"} in space
        assert BackendReply(text=b"{}") not in space and {"finish_reason": "stop"} not in space and 5 not in space
        base = env.unwrapped
        env.reset(seed=1)
        for action in (answer(turn(10)), {"text": answer(turn(10)), "finish_reason": "STOP"},
                       BackendReply(text=answer(turn(10)), choices=1)):
            signals, response, reason = base.read(action)
            assert reason is None and len(signals) == 1 and response is not None
        signals, _, reason = base.read({"text": answer(turn(10)), "finish_reason": "length"})
        assert signals is None and "finish reason" in reason
        assert base.read(42)[0] is None  # not a reply at all: refused, not a crash
    finally:
        env.close()


def test_a_reading_left_over_from_the_last_episode_says_nothing_of_the_next():
    """An answer reading's collision belongs to its episode: a reset forgets it (second read)."""
    from safeembodai_core.models import GroundTruth

    env = gymnasium.make("safeembodai/flatland-v0")
    action = ({"command": 0, "direction": 0, "distance": np.float32(1), "angle": np.float32(10)},)
    try:
        env.reset(seed=1)
        env.unwrapped._sensed_truth = GroundTruth(collision="struck", hit="labbot")  # as answer_reading leaves it
        env.reset(seed=2)
        _, _, _, _, info = env.step(action)
        assert info["collision"] is None
    finally:
        env.close()
