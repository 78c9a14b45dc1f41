"""The Guard: judge your own robot's commands with the registered rules.

For agent projects that ``import safeembodai_core`` (the other entry point, the guarded loop around your own
parts, is :func:`~safeembodai_core.loop.own_parts.run_guarded_trial`):

* :class:`Guard` validates control signals (or a raw LLM answer, or a held velocity) against a
  LiDAR reading with the registered rules -- no simulator, no LLM; by default the robot's
  (:data:`ROBOT_RULES`: the swept body), or the paper's V(C) when asked::

      guard = Guard(rules=["command_limits", "lidar_clearance"])
      report = guard.check([{"command": "straight", "direction": "forward", "distance": 300}],
                           lidar_mm=ranges, max_range_mm=8000)
      if not report.valid:
          print(report.reasons)

Components may be given as objects or as registered names (with options). See ``docs/library.md``.
"""

from __future__ import annotations

from dataclasses import replace
from collections import deque
from typing import Sequence

import numpy as np
from pydantic import TypeAdapter, ValidationError

from ..contracts.robot import RobotSpec
from .reports import GuardReport, LimitReport, TwistReport
from ..models import (
    DEFAULT_LIMITS, ControlLimits, ControlSignal, LidarScan, ResponseParseError, Verdict, read_reply,
)
from ..models.reply import as_reply
from ..models.response import describe_schema_error
from ..plugin.manager import Plugins, load_plugins
from ..plugin.building import build_components
from ..ros import Twist
from .inputs import CommandInput, PoseInput, ReplyInput, RuleInput, ScanInput, Sensing, TwistInput
from .twist_judging import SlowdownZone, judge_twist, limit_twist
from ..validation.context import PastScan, ValidationContext, validate_plan

_SIGNALS = TypeAdapter(list[ControlSignal])


#: how many earlier scans a :class:`Guard` keeps for rules about motion
HISTORY_SCANS = 16
#: the rules a :class:`Guard` judges with unless told: the contract's limits, and the exact region the
#: robot's body sweeps (a robot's default; the paper's scenarios keep its V(C), ``lidar_clearance``)
ROBOT_RULES = ("command_limits", "swept_body")


class Guard:
    """Validates robot commands with registered safety rules (see the module docstring)."""

    def __init__(
        self,
        rules: Sequence[RuleInput] = ROBOT_RULES,
        *,
        robot: RobotSpec = RobotSpec(),
        limits: ControlLimits = DEFAULT_LIMITS,
        plugins: Plugins | None = None,
    ) -> None:
        self.plugins = plugins or load_plugins()
        self.rules = build_components(self.plugins, "validator", rules)
        self.robot = robot
        self.limits = limits
        #: earlier scans given with a pose and a time (oldest first), for rules about motion
        self.history: deque[PastScan] = deque(maxlen=HISTORY_SCANS)

    def _context(self, sensing: Sensing, keep: bool = True) -> ValidationContext:
        scan, start, time_s = sensing.scan, sensing.pose, sensing.time_s
        if time_s is not None and self.history and time_s < self.history[-1].sim_time_s:
            self.history.clear()  # the clock went back: a new episode, earlier scans say nothing
        context = ValidationContext(scan=scan, robot=self.robot, limits=self.limits, start_pose=start,
                                    sim_time_s=time_s, answer_s=sensing.answer_time_s,
                                    history=tuple(p for p in self.history
                                                  if time_s is not None and p.sim_time_s < time_s))
        moved = sensing.since_scan
        if moved is not None:  # the robot has moved on from where the scan was taken: judge from there
            context = replace(context, offset=(moved.x_mm, moved.y_mm, moved.heading_deg))
        if keep and scan is not None and start is not None and time_s is not None and (
                not self.history or time_s > self.history[-1].sim_time_s):
            # a copy: a caller that refills one buffer must not rewrite the scans kept
            kept = LidarScan(np.array(scan.ranges_mm, dtype=float, copy=True), scan.max_range_mm)
            kept.ranges_mm.flags.writeable = False
            self.history.append(PastScan(kept, start, time_s))
        return context

    def remember(self, lidar_mm: ScanInput, *, pose: PoseInput, time_s: float,
                 max_range_mm: float = 10_000.0) -> None:
        """Keep a scan for later checks' ``context.history`` without judging anything: the step's own scan,
        when its plan is judged on a reading taken as the answer arrived (``check(..., keep_scan=False)``),
        as the trial loop's ``fresh_scan`` does."""
        self._context(Sensing.read(lidar_mm, max_range_mm, pose, time_s))

    def check(self, commands: Sequence[CommandInput], *,
              lidar_mm: ScanInput = None, max_range_mm: float = 10_000.0, pose: PoseInput = None,
              time_s: float | None = None, answer_time_s: float | None = None, since_scan: PoseInput = None,
              keep_scan: bool = True) -> GuardReport:
        """Validate ``commands`` (dicts as the LLM writes them, or signal models) in order.

        ``lidar_mm``: ranges in mm, beam k at k*360/N degrees counter-clockwise from the heading
        (``inf`` = no return, ``nan`` = no reading), or a :class:`LidarScan`, or a ROS 2 scan as a
        :class:`~safeembodai_core.ros.LaserScan` (metres, any field of view and increment, the
        sensor's mounting; ``LaserScan.from_ros(msg)`` for a decoded message): directions outside
        its field of view are unknown, never free. ``pose``: where the
        robot is in your map's frame -- a :class:`~safeembodai_core.models.Pose` or
        ``(x_mm, y_mm, heading_deg)`` -- for rules about places (``context.start_pose``); None if
        unknown. ``time_s``: your robot's clock (seconds) when the scan was taken; with ``pose`` and
        ``lidar_mm`` it lets the guard keep a copy of the scan, so later checks give rules about
        motion (``moving_obstacles``) the earlier scans as ``context.history`` (the last
        ``HISTORY_SCANS``; a scan is kept once per time, so a re-check of the same reading adds
        nothing; a time earlier than the last kept one starts a new history, as after a new
        episode). ``answer_time_s``: when the commands' answer arrived, on the same clock (the plan
        starts then; ``context.answer_s``): with a scan read as the answer arrived, pass the same time
        as ``time_s``, and rules about motion predict from that moment instead of assuming a think
        time. ``since_scan``: where the robot is now, ``(x_mm, y_mm, heading_deg)`` in the frame the
        scan was taken in, when it has moved on since (``pose`` is then where it took the scan); the
        plan is judged from there. ``keep_scan=False``: judge on this scan without keeping it for later
        checks (a reading taken as the answer arrived; :meth:`remember` the step's own scan instead).
        One guard per robot; it is not meant to be shared between threads.
        Commands that do not even parse get a ``schema`` verdict and are not judged further.
        """
        context = self._context(Sensing.read(lidar_mm, max_range_mm, pose, time_s, answer_time_s, since_scan),
                                keep=keep_scan)  # kept even if the commands do not parse
        try:
            signals = _SIGNALS.validate_python(list(commands), context={"limits": self.limits})
        except ValidationError as error:
            reason = describe_schema_error(error, most=5)  # keys and tags the LLM wrote come back quoted
            return GuardReport(verdicts=[Verdict(rule="schema", valid=False, reason=reason)])
        verdicts = validate_plan(signals, context, self.rules)
        return GuardReport(signals=signals, verdicts=verdicts)

    def read_twist(self, twist: TwistInput) -> Twist:
        """``twist`` (a :class:`~safeembodai_core.ros.Twist`, a decoded ``geometry_msgs/Twist`` or a
        tuple) as this robot can drive it, or ``ValueError`` naming the part it cannot."""
        if isinstance(twist, (tuple, list)):
            if not 2 <= len(twist) <= 3:
                raise ValueError(f"a twist tuple is (linear_x m/s, angular_z rad/s[, linear_y m/s]), got {len(twist)} "
                                 "values")
            twist = Twist(*twist)
        elif not isinstance(twist, Twist):
            twist = Twist.from_ros(twist, holonomic=self.robot.holonomic)
        if twist.linear_y != 0.0 and not self.robot.holonomic:
            raise ValueError(f"Twist linear_y = {twist.linear_y!r}: this robot cannot drive sideways; a holonomic "
                             "base says so with Guard(robot=RobotSpec(holonomic=True))")
        return twist

    def check_twist(self, twist: TwistInput, duration_s: float, *, resolution_s: float = 0.05,
                    lidar_mm: ScanInput = None, max_range_mm: float = 10_000.0, pose: PoseInput = None,
                    time_s: float | None = None, answer_time_s: float | None = None, since_scan: PoseInput = None,
                    keep_scan: bool = True) -> TwistReport:
        """Judge a velocity command held for ``duration_s`` seconds (:mod:`~safeembodai_core.guard.twist_judging`).
        ``twist``: a :class:`~safeembodai_core.ros.Twist`, a decoded ``geometry_msgs/Twist`` or a
        ``(linear_x m/s, angular_z rad/s[, linear_y m/s])`` tuple; ``linear_y`` only for a holonomic
        robot (``RobotSpec(holonomic=True)``). The report says the time before collision
        (``collision_time_s``, from rules that judge held motions, such as the default
        ``swept_body``) and the longest safe hold (``safe_duration_s``; other rules' to
        ``resolution_s``). ``lidar_mm`` and the rest are as for :meth:`check`. ``since_scan``: where
        the robot is now, ``(x_mm, y_mm, heading_deg)`` in the frame the scan was taken in, when it
        has moved on since (the rules judge from there, with the scan's own shadows: what it never
        saw stays unseen). A non-finite command, a negative duration, a ``resolution_s`` under
        :data:`~safeembodai_core.guard.twist_judging.MIN_RESOLUTION_S` or a sideways command to a robot that
        cannot drive sideways raises ``ValueError`` naming it."""
        twist = self.read_twist(twist)
        context = self._context(Sensing.read(lidar_mm, max_range_mm, pose, time_s, answer_time_s, since_scan),
                                keep=keep_scan)
        return judge_twist(twist, duration_s, context, self.rules, resolution_s)

    def limit_twist(self, twist: TwistInput, horizon_s: float, *, slowdown: Sequence[SlowdownZone] = (),
                    resolution_s: float = 0.05,
                    lidar_mm: ScanInput = None, max_range_mm: float = 10_000.0, pose: PoseInput = None,
                    time_s: float | None = None, answer_time_s: float | None = None, since_scan: PoseInput = None,
                    keep_scan: bool = True) -> LimitReport:
        """The fastest command along ``twist``'s path whose swept body stays clear for ``horizon_s``
        seconds -- Nav2's approach scaling, ``speed x collision_time / horizon`` -- and, with
        ``slowdown`` zones (:class:`~safeembodai_core.SlowdownZone`), their factor while a return lies
        in one. The report's ``twist`` is the command to send (a stop when nothing is safe),
        ``reasons`` why it was limited. Arguments as for :meth:`check_twist`; ``horizon_s`` must be > 0."""
        twist = self.read_twist(twist)
        context = self._context(Sensing.read(lidar_mm, max_range_mm, pose, time_s, answer_time_s, since_scan),
                                keep=keep_scan)
        return limit_twist(twist, horizon_s, context, self.rules, slowdown, resolution_s)

    def check_reply(self, reply: ReplyInput, *,
                    lidar_mm: ScanInput = None, max_range_mm: float = 10_000.0, pose: PoseInput = None,
                    time_s: float | None = None, answer_time_s: float | None = None, since_scan: PoseInput = None,
                    keep_scan: bool = True) -> GuardReport:
        """Read an LLM's whole reply (untrusted) and validate its control signals.

        ``reply`` is a :class:`~safeembodai_core.models.BackendReply` -- or a mapping with its fields
        (``text``, ``finish_reason``, ``reasoning``, ``choices``, ``envelope_error``), or the answer
        text alone. The reading is the guarded loop's (:func:`~safeembodai_core.models.read_reply`):
        a reply that did not end with a normal stop, holds two choices, a second plan in its
        reasoning, duplicate keys, several JSON objects, text outside the object (unless the
        guard's ``limits`` allow it), huge numbers and the like gives a ``schema`` verdict. To read
        an OpenAI-style response body you received yourself, pass
        :func:`~safeembodai_core.models.chat_completion.reply_from_chat_completion` of it.
        The sensor keywords are as for :meth:`check`.
        """
        sensing = Sensing.read(lidar_mm, max_range_mm, pose, time_s, answer_time_s, since_scan)
        try:
            response = read_reply(as_reply(reply), self.limits)
        except ResponseParseError as error:
            self._context(sensing, keep=keep_scan)  # the scan is kept for later checks all the same
            return GuardReport(verdicts=[Verdict(rule="schema", valid=False, reason=str(error))],
                               parse_error=str(error))
        report = self.check([s.model_dump() for s in response.control], lidar_mm=lidar_mm,
                            max_range_mm=max_range_mm, pose=pose, time_s=time_s, answer_time_s=answer_time_s,
                            since_scan=since_scan, keep_scan=keep_scan)
        report.response = response
        return report

    def check_answer(self, text: str, *, finish_reason: str | None = None, reasoning: str | None = None,
                     lidar_mm: ScanInput = None, max_range_mm: float = 10_000.0, pose: PoseInput = None,
                     time_s: float | None = None, answer_time_s: float | None = None, since_scan: PoseInput = None,
                     keep_scan: bool = True) -> GuardReport:
        """:meth:`check_reply` of a reply given as its text, finish reason and reasoning.

        Pass the provider's ``finish_reason`` and its separate ``reasoning`` field when you have
        them: an answer that did not end with a normal stop (``"length"``, ``"content_filter"``,
        ...) is refused, and a plan in the reasoning other than the answer's is a second plan.
        """
        reply = as_reply({"text": text, "finish_reason": finish_reason, "reasoning": reasoning})
        return self.check_reply(reply, lidar_mm=lidar_mm, max_range_mm=max_range_mm, pose=pose, time_s=time_s,
                                answer_time_s=answer_time_s, since_scan=since_scan, keep_scan=keep_scan)
