"""``LLMAgent`` feeds a refusal back as the trial loop does: the step's failure lines so far, and the same
as data with each rule's advice (what a simulated pilot reads), from ``info["feedback"]`` and
``info["refusals"]``."""

from __future__ import annotations

import json

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium", reason='pip install -e ".[gym]"')

from safeembodai_core.gym import SafeEmbodAIGuard  # noqa: E402
from safeembodai_core.integrations.gym.agents import LLMAgent  # noqa: E402
from safeembodai_core.loop.guarded_step import feedback, feedback_refusals  # noqa: E402
from safeembodai_core.models import Attempt, BackendReply, read_reply  # noqa: E402


def _answer(*control) -> str:
    return json.dumps({"perception": [{"input": "human_instruction", "result": "ok", "is_attack": False}],
                       "planning": "p", "control": list(control)})


class _Scripted:
    """A backend object for ``LLMAgent``: the replies in turn; every prompt it was given kept."""

    def __init__(self, *texts: str) -> None:
        self.texts, self.prompts = list(texts), []

    def complete(self, prompt, rng):
        self.prompts.append(prompt)
        return BackendReply(text=self.texts[len(self.prompts) - 1])

    def close(self):
        pass


def _facing_something(env) -> tuple[dict, dict, float, float]:
    """An episode whose nearest return is under 450 mm: (obs, info, its bearing in degrees, its range)."""
    for seed in range(100):
        obs, info = env.reset(seed=seed)
        if obs["lidar"].min() < 450:
            beam = int(np.argmin(obs["lidar"]))
            return obs, info, beam if beam <= 180 else beam - 360, float(obs["lidar"][beam])
    raise AssertionError("no seed put the robot near anything")


def test_a_refusals_feedback_and_its_advice_reach_the_agents_next_prompt_as_the_loops_would():
    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0", action_format="text"))
    try:
        obs, info, bearing, ahead = _facing_something(env)
        face = {"command": "turn", "direction": "left" if bearing > 0 else "right", "angle": max(abs(bearing), 1)}
        into_it = _answer(face, {"command": "straight", "direction": "forward", "distance": min(399, int(ahead))})
        backend = _Scripted(into_it, into_it, _answer({"command": "turn", "direction": "left", "angle": 10}))
        agent = LLMAgent(backend, max_range_mm=float(env.observation_space["lidar"].high[0]))
        step = info["step"]
        verdicts = []
        for attempt in range(2):  # refused twice at the same step
            obs, _, _, _, info = env.step(agent.act(obs, info))
            assert info["refused"] and info["step"] == step and info["attempt"] == attempt + 1
            base = env.unwrapped
            verdicts.append(env.guard.check(read_reply(BackendReply(text=into_it)).control, lidar_mm=base.scan,
                                            pose=base.pose, time_s=base.time_s, keep_scan=False).verdicts)
            # what the loop's retry prompt adds for this answer: the same lines, the same data
            loops = Attempt(index=attempt, response=read_reply(BackendReply(text=into_it)), verdicts=verdicts[-1])
            assert info["feedback"] == feedback(attempt, loops)
            assert info["refusals"] == [r.model_dump(mode="json") for r in feedback_refusals(attempt, loops)]
        agent.act(obs, info)
        first, _, third = backend.prompts
        assert first.refusals == () and not any("attempt" in line for line in info["reasons"])
        # the third prompt carries both refusals of the step, each with the rule's advice
        assert [r.attempt for r in third.refusals] == [1, 2]
        assert all(r.rule == "lidar_clearance" and r.signal_index == 1 and r.advice is not None
                   and r.advice.safe_mm is not None and r.advice.safe_mm < min(399, int(ahead)) for r in third.refusals)
        assert "attempt 1 (refused plan: " in third.user_text and "attempt 2 (refused plan: " in third.user_text
    finally:
        env.close()


def test_a_new_step_starts_with_no_feedback():
    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/flatland-v0", action_format="text"))
    try:
        obs, info = env.reset(seed=3)
        backend = _Scripted(_answer({"command": "turn", "direction": "left", "angle": 10}),
                            _answer({"command": "turn", "direction": "left", "angle": 10}))
        agent = LLMAgent(backend, max_range_mm=float(env.observation_space["lidar"].high[0]))
        agent._failures, agent._refusals, agent._step = ["stale"], [], info["step"] - 1  # left from another episode
        obs, _, _, _, info = env.step(agent.act(obs, info))
        agent.act(obs, info)
        assert [p.refusals for p in backend.prompts] == [(), ()]
        assert all("stale" not in p.user_text for p in backend.prompts)
    finally:
        env.close()
