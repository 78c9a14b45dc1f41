"""``SafeEmbodAIGuard``: the paper's safety validation around any Gymnasium agent.

Every action is judged before the room sees it, by :class:`~safeembodai_core.guard.guard.Guard` --
:func:`~safeembodai_core.validation.context.validate_plan` with the arm's validators, from the step's
(attacked) LiDAR scan, the world's pose and clock (the guard keeps the episode's earlier scans for
rules about motion, as the trial loop does), each signal from the pose the earlier ones lead to,
exactly as Algorithm 1 judges an LLM's plan; with the arm's ``fresh_scan``, on the world read as the
answer arrives (:meth:`SafeEmbodAIEnv.answer_reading`), as the loop does. A refused plan is not
executed: the step comes back with the same observation, ``info["refused"]`` and the rules'
``info["reasons"]``, cost 1, and the agent may try again until the arm's ``failure_threshold`` is spent
(:meth:`SafeEmbodAIEnv.refuse`). With the arm's ``on_exhausted: enforce``, a refusal that spends them
hands the env the rules' cut of the step's last parsed, refused plan, judged again on what that plan was
judged on (:func:`~safeembodai_core.loop.enforce.enforce_cut`, as the trial loop does): it runs, or the
step holds.

Wrap the environment ``gymnasium.make`` returns, before any wrapper of your own: a refusal goes
straight to the unwrapped env, so wrappers between the two would not see it.
"""

from __future__ import annotations

from typing import Any, Sequence, cast

import gymnasium

from ...guard.guard import Guard
from ...loop.enforce import enforce_cut, nothing_to_cut
from ...loop.fresh_scan import require_sense
from ...models import Attempt, Enforced
from .env import SafeEmbodAIEnv


class SafeEmbodAIGuard(gymnasium.Wrapper):
    """Applies the scenario arm's validators (or ``rules``: names, refs or ``Validator`` objects) to
    every action of a :class:`SafeEmbodAIEnv`; see the module docstring."""

    def __init__(self, env: gymnasium.Env, rules: Sequence[Any] | None = None) -> None:
        super().__init__(env)
        base = env.unwrapped
        if not isinstance(base, SafeEmbodAIEnv):
            raise TypeError(f"SafeEmbodAIGuard wraps a SafeEmbodAIEnv, got {type(base).__name__}")
        if base.arm.fresh_scan:
            require_sense(base.world)  # before any step: a room that cannot read as the answer arrives
        rules = list(base.arm.validators) if rules is None else list(rules)
        self.guard = Guard(rules, robot=base.world.robot, limits=base.limits, plugins=base.plugins)
        #: the step's last parsed, refused plan: (step, attempt, signals, verdicts, what it was judged on)
        self._refused: tuple[int, int, list[Any], list[Any], dict[str, Any]] | None = None

    def reset(self, **kwargs: Any):
        self.guard.history.clear()  # a new episode: the last one's scans say nothing about this one
        self._refused = None
        return self.env.reset(**kwargs)

    def step(self, action: Any):
        base = cast(SafeEmbodAIEnv, self.env.unwrapped)  # checked in __init__
        # on_exhausted: enforce -- this attempt is the step's last: a refusal runs the rules' cut or holds
        last = base.arm.on_exhausted == "enforce" and base._attempt >= base.arm.failure_threshold
        signals, response, reason = base.read(action)
        if signals is None:  # not even the actuation contract: the env refuses it itself
            if last:  # never enforced itself; the step's last parsed, refused answer is cut instead
                assert reason is not None  # read() gives a reason with no signals
                return base.refuse(base._refusal(reason), cut=self._cut(base), attempt=base.refused_reading(reason))
            return self.env.step(action)
        # the clock too: the guard keeps each step's scan, so rules about motion get the trial's earlier
        # scans as context.history, as in the trial loop
        if base.arm.fresh_scan:  # judged on the world as the answer arrives; the step's scan joins the history
            reading = base.answer_reading()
            if base.time_s is not None:
                self.guard.remember(base.scan, pose=base.pose, time_s=base.time_s)
            judged: dict[str, Any] = dict(lidar_mm=reading.lidar, pose=reading.pose, time_s=reading.sim_time_s,
                                          answer_time_s=reading.sim_time_s)
            report = self.guard.check(signals, **judged, keep_scan=False)
            if not report.valid and base.world.outcome() is not None:  # struck while it thought: no retry
                return base.end_refused(report.reasons)
        else:
            judged = dict(lidar_mm=base.scan, pose=base.pose, time_s=base.time_s)
            report = self.guard.check(signals, **judged)
        if not report.valid:
            self._refused = (base._step, base._attempt, signals, report.verdicts, judged)
            answer = (None if response is None  # as the loop records the answer it refused: the retry's feedback
                      else Attempt(index=base._attempt, response=response, verdicts=report.verdicts))
            return base.refuse(report.reasons, cut=self._cut(base) if last else None, attempt=answer)
        return self.env.step(action)

    def _cut(self, base: SafeEmbodAIEnv) -> Enforced:
        """The rules' cut of the step's last parsed, refused plan, judged again on the reading it was judged
        on (:func:`~safeembodai_core.loop.enforce.enforce_cut`, as the trial loop does)."""
        if self._refused is None or self._refused[0] != base._step:
            return nothing_to_cut()
        _, attempt, signals, verdicts, judged = self._refused
        return enforce_cut(attempt, signals, verdicts,
                           lambda plan: self.guard.check(plan, **judged, keep_scan=False).verdicts)
