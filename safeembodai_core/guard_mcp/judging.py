"""A motion an agent asks for, judged by the Guard on the robot's own latest scan.

:meth:`MotionJudge.plan` writes a :class:`~.calls.Motion` as the base will drive it, a list of
:class:`Step`: ``publish_once`` is its message held for ``hold_s`` (the policy's horizon, at least the
base's ``cmd_vel_timeout_s``); ``publish_for_durations`` is each message held for its duration, and
when the last message moves, that message held ``hold_s`` more (the base keeps it until its timeout,
and the horizon covers the agent's next call).

* ``mode: refuse`` -- :meth:`MotionJudge.judge` checks each step with ``Guard.check_twist`` from
  where the steps before it leave the robot (the scan's frame, odometry since the scan first), and
  refuses at the first step that touches a return or unseen space, or a speed beyond the robot
  file's ``velocity_smoother`` limits. A refusal carries its numbers (:attr:`Judgement.safe`: the
  step, how long and how far of it is safe, the speed that would be) and advice in words.
* ``mode: limit`` -- :meth:`MotionJudge.limit` slows one step's twist along its path to the robot's
  limits and then to what stays clear for ``window_s`` (``Guard.limit_twist``: Nav2's approach scaling).

A running motion is re-judged before each slice on the newest scan: the rest of its plan over the
next ``window_s`` seconds (:meth:`MotionJudge.ahead`), ``window_s`` being at least a slice plus the
base's timeout, so that what runs while the next slice is judged was judged already.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

from ..geometry.sweep import Motion as Sweep
from ..ros.robot_file import RobotFile
from ..ros.twist import Twist
from .calls import Motion
from .policy import Policy
from .senses import View

STOP = Twist(0.0, 0.0)


@dataclass(frozen=True)
class Step:
    """``twist`` held ``seconds``; ``what`` names it for the agent (``messages[2]``, ``msg``, ...)."""

    twist: Twist
    seconds: float
    what: str
    index: int
    tail: bool = False


@dataclass(frozen=True)
class Judgement:
    """``ok``, or why not (``reasons``), how to amend (``advice``) and the numbers (``safe``); ``factor``:
    the speed kept (limit mode)."""

    ok: bool
    reasons: list[str] = field(default_factory=list)
    advice: list[str] = field(default_factory=list)
    safe: dict[str, Any] = field(default_factory=dict)
    factor: float = 1.0


def _shown(twist: Twist) -> str:
    sideways = f", linear.y {twist.linear_y:g} m/s" if twist.linear_y else ""
    return f"linear.x {twist.linear_x:g} m/s{sideways}, angular.z {twist.angular_z:g} rad/s"


def after(offset: tuple[float, float, float], twist: Twist, seconds: float) -> tuple[float, float, float]:
    """Where ``twist`` held ``seconds`` leaves a robot at ``offset`` (x_mm, y_mm, heading_deg)."""
    dx, dy, turned = Sweep(twist.linear_x * 1000.0, twist.linear_y * 1000.0, twist.angular_z, seconds).pose_at(seconds)
    x, y, heading = offset
    c, s = math.cos(math.radians(heading)), math.sin(math.radians(heading))
    return x + dx * c - dy * s, y + dx * s + dy * c, heading + math.degrees(turned)


class MotionJudge:
    """Judges motions for one robot under one policy (module docstring)."""

    def __init__(self, guard: Any, robot: RobotFile, policy: Policy) -> None:
        self.guard, self.mode = guard, policy.mode
        self.timeout_s = float(robot.cmd_vel_timeout_s)
        self.hold_s = max(policy.horizon_s, self.timeout_s)
        self.window_s = max(policy.horizon_s, policy.slice_s + self.timeout_s)
        smoother = robot.velocity_smoother
        self.limits = {"linear.x": (smoother.min_velocity[0], smoother.max_velocity[0], "m/s"),
                       "linear.y": (smoother.min_velocity[1], smoother.max_velocity[1], "m/s"),
                       "angular.z": (smoother.min_velocity[2], smoother.max_velocity[2], "rad/s")}

    def plan(self, motion: Motion) -> list[Step]:
        """The motion as the base drives it (module docstring)."""
        if motion.kind == "publish_once":
            return [Step(motion.holds[0].twist, self.hold_s, "msg", 0)]
        steps = [Step(hold.twist, hold.duration_s, f"messages[{k}]", k) for k, hold in enumerate(motion.holds)]
        if steps and steps[-1].twist != STOP:
            steps.append(replace(steps[-1], seconds=self.hold_s, tail=True))
        return steps

    def ahead(self, steps: list[Step], elapsed_s: float) -> list[Step]:
        """What of ``steps`` is left ``elapsed_s`` seconds in, over the next ``window_s`` seconds."""
        left, start, window = [], 0.0, self.window_s
        for step in steps:
            end = start + step.seconds
            if end > elapsed_s and window > 0:
                seconds = min(end - max(start, elapsed_s), window)
                left.append(replace(step, seconds=seconds))
                window -= seconds
            start = end
        return left

    def within_limits(self, twist: Twist) -> tuple[float, list[str]]:
        """The largest factor <= 1 that keeps ``twist`` within the robot file's velocity limits, and why."""
        factor, reasons = 1.0, []
        for name, value in (("linear.x", twist.linear_x), ("linear.y", twist.linear_y), ("angular.z", twist.angular_z)):
            low, high, unit = self.limits[name]
            bound = high if value > 0 else low
            if abs(value) > abs(bound):
                factor = min(factor, abs(bound) / abs(value))
                reasons.append(f"{name} {value:g} {unit} is beyond the robot's "
                               f"{'max' if value > 0 else 'min'}_velocity {bound:g} {unit}")
        return factor, reasons

    def judge(self, steps: list[Step], view: View) -> Judgement:
        """``mode: refuse``: every step from where the ones before leave the robot (module docstring)."""
        for step in steps:
            factor, reasons = self.within_limits(step.twist)
            if reasons:
                slowed = step.twist.scaled(factor)
                return Judgement(False, [f"{step.what} ({_shown(step.twist)}): refused", *reasons],
                                 [f"slow {step.what} to {_shown(slowed)} at most"],
                                 {"message": step.index, "slow_to_m_s": slowed.linear_x,
                                  "slow_to_rad_s": slowed.angular_z})
        offset, elapsed = view.since_scan or (0.0, 0.0, 0.0), 0.0
        for step in steps:
            if step.seconds > 0 and step.twist != STOP:
                report = self.guard.check_twist(step.twist, step.seconds, lidar_mm=view.scan,
                                                since_scan=None if offset == (0.0, 0.0, 0.0) else offset)
                if not report.valid:
                    return self._refused(step, report, elapsed, view)
                offset = after(offset, step.twist, step.seconds)
            elapsed += step.seconds
        return Judgement(True)

    def _refused(self, step: Step, report: Any, elapsed: float, view: View) -> Judgement:
        twist, safe_s = step.twist, report.safe_duration_s
        factor = safe_s / step.seconds
        slowed = twist.scaled(factor)
        millimetres, degrees = abs(twist.linear_x) * safe_s * 1000.0, math.degrees(abs(twist.angular_z) * safe_s)
        what = (f"the base's hold of {step.what} after it ends ({step.seconds:g} s: cmd_vel_timeout or the horizon)"
                if step.tail else f"{step.what} ({_shown(twist)}) held {step.seconds:g} s")
        reasons = [f"{what}, starting {elapsed:g} s from now: refused on the robot's own scan "
                   f"({view.age_s:.2f} s old)", *report.reasons]
        if safe_s < 0.01:
            advice = [f"nothing of {step.what} is safe from where the robot will be: choose another direction, "
                      "or turn or back away first"]
        else:
            reach = f"at most {millimetres:.0f} mm" if twist.linear_x else f"at most {degrees:.0f} degrees"
            advice = [f"{reach} of {step.what} is safe ({safe_s:.2f} s at this speed)",
                      f"or slow {step.what} to {_shown(slowed)}"]
        if step.tail:
            advice.insert(0, "end with a stop message (all zeros, duration 0): the base holds the last message "
                             f"for {self.timeout_s:g} s after it ends")
        safe = {"message": step.index, "after_the_last_message": step.tail, "elapsed_s": round(elapsed, 3),
                "safe_duration_s": round(safe_s, 3), "at_most_mm": round(millimetres, 1),
                "at_most_deg": round(degrees, 1), "slow_to_m_s": round(slowed.linear_x, 4),
                "slow_to_rad_s": round(slowed.angular_z, 4), "collision_time_s": report.collision_time_s}
        return Judgement(False, reasons, advice, safe, factor)

    def limit(self, twist: Twist, view: View) -> Judgement:
        """``mode: limit``: ``twist`` slowed to the robot's limits, then to what stays clear for ``window_s``."""
        bound, reasons = self.within_limits(twist)
        if twist == STOP:
            return Judgement(True)
        limited = self.guard.limit_twist(twist.scaled(bound), self.window_s, lidar_mm=view.scan,
                                         since_scan=view.since_scan)
        factor = bound * limited.factor
        reasons += limited.reasons
        if factor <= 0.0:
            return Judgement(False, [f"{_shown(twist)}: nothing of it stays clear for {self.window_s:g} s on the "
                                     f"robot's own scan ({view.age_s:.2f} s old): stop", *reasons],
                             ["choose another direction, or turn or back away first"], factor=0.0)
        return Judgement(True, reasons, [], {"slowed_to_m_s": round(twist.linear_x * factor, 4),
                                             "slowed_to_rad_s": round(twist.angular_z * factor, 4)}, factor)
