"""``SafeEmbodAIGuard``: the paper's safety validation around any Gymnasium agent.

Every action is judged before the room sees it, by :class:`~safeembodai_core.api.Guard` --
:func:`~safeembodai_core.validation.validate_plan` with the arm's validators, from the step's
(attacked) LiDAR scan and the world's pose, each signal from the pose the earlier ones lead to,
exactly as Algorithm 1 judges an LLM's plan. A refused plan is not executed: the step comes back
with the same observation, ``info["refused"]`` and the rules' ``info["reasons"]``, cost 1, and
the agent may try again until the arm's ``failure_threshold`` is spent
(:meth:`SafeEmbodAIEnv.refuse`).

Wrap the environment ``gymnasium.make`` returns, before any wrapper of your own: a refusal goes
straight to the unwrapped env, so wrappers between the two would not see it.
"""

from __future__ import annotations

from typing import Any, Sequence

import gymnasium

from ...api import Guard
from .env import SafeEmbodAIEnv


class SafeEmbodAIGuard(gymnasium.Wrapper):
    """Applies the scenario arm's validators (or ``rules``: names, refs or ``Validator`` objects) to
    every action of a :class:`SafeEmbodAIEnv`; see the module docstring."""

    def __init__(self, env: gymnasium.Env, rules: Sequence[Any] | None = None) -> None:
        super().__init__(env)
        base = env.unwrapped
        if not isinstance(base, SafeEmbodAIEnv):
            raise TypeError(f"SafeEmbodAIGuard wraps a SafeEmbodAIEnv, got {type(base).__name__}")
        rules = list(base.arm.validators) if rules is None else list(rules)
        self.guard = Guard(rules, robot=base.world.robot, limits=base.limits, plugins=base.plugins)

    def step(self, action: Any):
        base: SafeEmbodAIEnv = self.env.unwrapped
        signals, _, _ = base.read(action)
        if signals is None:  # not even the actuation contract: the env refuses it itself
            return self.env.step(action)
        report = self.guard.check(signals, lidar_mm=base.scan, pose=base.pose)
        if not report.valid:
            return base.refuse(report.reasons)
        return self.env.step(action)
