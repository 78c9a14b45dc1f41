"""The library API: guard your own robot's commands, or run the guarded loop around your own parts.

Two entry points for agent projects that ``import safeembodai_core``:

* :class:`Guard` validates control signals (or a raw LLM answer, or a held velocity) against a
  LiDAR reading with the registered rules -- no simulator, no LLM; by default the robot's
  (:data:`ROBOT_RULES`: the swept body), or the paper's V(C) when asked::

      guard = Guard(rules=["command_limits", "lidar_clearance"])
      report = guard.check([{"command": "straight", "direction": "forward", "distance": 300}],
                           lidar_mm=ranges, max_range_mm=8000)
      if not report.valid:
          print(report.reasons)

* :func:`run_guarded_trial` runs Algorithm 1 inside the step loop around *your* environment and
  backend objects, with built-in (or your own) prompt builder, perception, store and validators.

Components may be given as objects or as registered names (with options). See ``docs/library.md``.
"""

from __future__ import annotations

import math
from dataclasses import replace
from collections import deque
from typing import Any, Iterable, Sequence

import numpy as np
from pydantic import TypeAdapter, ValidationError

from .components import Environment, LLMBackend, RobotSpec, as_llm_backend
from .guard_reports import GuardReport, LimitReport, TwistReport
from .loop import Defences, LoopSettings, TrialParts, run_trial
from .loop.trial import DEFAULT_INSTRUCTION
from .models import (
    DEFAULT_LIMITS,
    ControlLimits,
    ControlSignal,
    LidarScan,
    Pose,
    ResponseParseError,
    StepRecord,
    TrialResult,
    TrialSpec,
    Verdict,
    read_reply,
)
from .models.reply import as_reply
from .models.response import describe_schema_error
from .plugins import Plugins, load_plugins
from .refs import ComponentRef, ref
from .ros import LaserScan, Twist
from .ros.laser_scan import finite_number
from .twist_judging import SlowdownZone, judge_twist, limit_twist
from .validation import PastScan, ValidationContext, validate_plan

_SIGNALS = TypeAdapter(list[ControlSignal])


def _pose(pose: Any) -> Pose | None:
    """A caller's pose (a Pose, a dict of its fields, or ``(x_mm, y_mm, heading_deg)``); finite or refused."""
    if pose is None:
        return None
    if not isinstance(pose, Pose):
        pose = Pose.model_validate(pose) if isinstance(pose, dict) else Pose(
            **dict(zip(("x_mm", "y_mm", "heading_deg"), pose, strict=True)))
    if not all(math.isfinite(v) for v in (pose.x_mm, pose.y_mm, pose.heading_deg)):
        raise ValueError(f"pose must be finite, got {pose!r}")
    return pose


def _components(plugins: Plugins, kind: str, items: Iterable[Any], seed: int = 0) -> list[tuple[str, Any]]:
    """Build named components (as the scenario runner does: ``label`` is the key, ``seed`` the trial's)."""
    built = []
    for item in items:
        if isinstance(item, (str, dict, ComponentRef)):
            r = ref(item)
            built.append((r.key, plugins.registry.build_ref(kind, r, seed=seed)))
        else:
            built.append((getattr(item, "name", type(item).__name__), as_llm_backend(item) if kind == "llm_backend"
                          else item))
    return built


#: how many earlier scans a :class:`Guard` keeps for rules about motion
HISTORY_SCANS = 16
#: the rules a :class:`Guard` judges with unless told: the contract's limits, and the exact region the
#: robot's body sweeps (a robot's default; the paper's scenarios keep its V(C), ``lidar_clearance``)
ROBOT_RULES = ("command_limits", "swept_body")


class Guard:
    """Validates robot commands with registered safety rules (see the module docstring)."""

    def __init__(
        self,
        rules: Sequence[Any] = ROBOT_RULES,
        *,
        robot: RobotSpec = RobotSpec(),
        limits: ControlLimits = DEFAULT_LIMITS,
        plugins: Plugins | None = None,
    ) -> None:
        self.plugins = plugins or load_plugins()
        self.rules = _components(self.plugins, "validator", rules)
        self.robot = robot
        self.limits = limits
        #: earlier scans given with a pose and a time (oldest first), for rules about motion
        self.history: deque[PastScan] = deque(maxlen=HISTORY_SCANS)

    def _context(self, lidar_mm: Any, max_range_mm: float, pose: Any, time_s: float | None,
                 answer_time_s: float | None = None, since_scan: Any = None, keep: bool = True) -> ValidationContext:
        scan = None
        if isinstance(lidar_mm, LaserScan):
            scan = lidar_mm.to_lidar_scan()  # ROS semantics and the sensor's mounting: safeembodai_core.ros
        elif lidar_mm is not None:
            scan = (lidar_mm if isinstance(lidar_mm, LidarScan)
                    else LidarScan(np.asarray(lidar_mm, dtype=float), max_range_mm))
        start = _pose(pose)
        if time_s is not None:
            time_s = finite_number("", "time_s", time_s, "seconds")
            if self.history and time_s < self.history[-1].sim_time_s:
                self.history.clear()  # the clock went back: a new episode, earlier scans say nothing
        if answer_time_s is not None:
            if time_s is None:
                raise ValueError("answer_time_s needs time_s: the scan's time on the same clock")
            answer_time_s = finite_number("", "answer_time_s", answer_time_s, "seconds")
            if answer_time_s < time_s:
                raise ValueError(f"answer_time_s must be finite and not before time_s ({time_s:g}), "
                                 f"got {answer_time_s!r}")
        context = ValidationContext(scan=scan, robot=self.robot, limits=self.limits, start_pose=start,
                                    sim_time_s=time_s, answer_s=answer_time_s, history=tuple(p for p in self.history
                                                                      if time_s is not None and p.sim_time_s < time_s))
        moved = _pose(since_scan)
        if moved is not None:  # the robot has moved on from where the scan was taken: judge from there
            context = replace(context, offset=(moved.x_mm, moved.y_mm, moved.heading_deg))
        if keep and scan is not None and start is not None and time_s is not None and (
                not self.history or time_s > self.history[-1].sim_time_s):
            # a copy: a caller that refills one buffer must not rewrite the scans kept
            kept = LidarScan(np.array(scan.ranges_mm, dtype=float, copy=True), scan.max_range_mm)
            kept.ranges_mm.flags.writeable = False
            self.history.append(PastScan(kept, start, time_s))
        return context

    def remember(self, lidar_mm: Any, *, pose: Any, time_s: float, max_range_mm: float = 10_000.0) -> None:
        """Keep a scan for later checks' ``context.history`` without judging anything: the step's own scan,
        when its plan is judged on a reading taken as the answer arrived (``check(..., keep_scan=False)``),
        as the trial loop's ``fresh_scan`` does."""
        self._context(lidar_mm, max_range_mm, pose, time_s)

    def check(self, commands: Sequence[Any], *, lidar_mm: Any = None, max_range_mm: float = 10_000.0,
              pose: Any = None, time_s: float | None = None, answer_time_s: float | None = None,
              since_scan: Any = None, keep_scan: bool = True) -> GuardReport:
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
        context = self._context(lidar_mm, max_range_mm, pose, time_s, answer_time_s,  # kept even if they do not parse
                                since_scan=since_scan, keep=keep_scan)
        try:
            signals = _SIGNALS.validate_python(list(commands), context={"limits": self.limits})
        except ValidationError as error:
            reason = describe_schema_error(error, most=5)  # keys and tags the LLM wrote come back quoted
            return GuardReport(verdicts=[Verdict(rule="schema", valid=False, reason=reason)])
        verdicts = validate_plan(signals, context, self.rules)
        return GuardReport(signals=signals, verdicts=verdicts)

    def read_twist(self, twist: Any) -> Twist:
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

    def check_twist(self, twist: Any, duration_s: float, *, lidar_mm: Any = None, max_range_mm: float = 10_000.0,
                    pose: Any = None, time_s: float | None = None, resolution_s: float = 0.05,
                    since_scan: Any = None) -> TwistReport:
        """Judge a velocity command held for ``duration_s`` seconds (:mod:`~safeembodai_core.twist_judging`).
        ``twist``: a :class:`~safeembodai_core.ros.Twist`, a decoded ``geometry_msgs/Twist`` or a
        ``(linear_x m/s, angular_z rad/s[, linear_y m/s])`` tuple; ``linear_y`` only for a holonomic
        robot (``RobotSpec(holonomic=True)``). The report says the time before collision
        (``collision_time_s``, from rules that judge held motions, such as the default
        ``swept_body``) and the longest safe hold (``safe_duration_s``; other rules' to
        ``resolution_s``). ``lidar_mm`` and the rest are as for :meth:`check`. ``since_scan``: where
        the robot is now, ``(x_mm, y_mm, heading_deg)`` in the frame the scan was taken in, when it
        has moved on since (the rules judge from there, with the scan's own shadows: what it never
        saw stays unseen). A non-finite command, a negative duration, a ``resolution_s`` under
        :data:`~safeembodai_core.twist_judging.MIN_RESOLUTION_S` or a sideways command to a robot that
        cannot drive sideways raises ``ValueError`` naming it."""
        twist = self.read_twist(twist)
        context = self._context(lidar_mm, max_range_mm, pose, time_s, since_scan=since_scan)
        return judge_twist(twist, duration_s, context, self.rules, resolution_s)

    def limit_twist(self, twist: Any, horizon_s: float, *, slowdown: Sequence[SlowdownZone] = (), lidar_mm: Any = None,
                    max_range_mm: float = 10_000.0, pose: Any = None, time_s: float | None = None,
                    resolution_s: float = 0.05, since_scan: Any = None) -> LimitReport:
        """The fastest command along ``twist``'s path whose swept body stays clear for ``horizon_s``
        seconds -- Nav2's approach scaling, ``speed x collision_time / horizon`` -- and, with
        ``slowdown`` zones (:class:`~safeembodai_core.SlowdownZone`), their factor while a return lies
        in one. The report's ``twist`` is the command to send (a stop when nothing is safe),
        ``reasons`` why it was limited. Arguments as for :meth:`check_twist`; ``horizon_s`` must be > 0."""
        twist = self.read_twist(twist)
        context = self._context(lidar_mm, max_range_mm, pose, time_s, since_scan=since_scan)
        return limit_twist(twist, horizon_s, context, self.rules, slowdown, resolution_s)

    def check_reply(
        self,
        reply: Any,
        *,
        lidar_mm: Any = None,
        max_range_mm: float = 10_000.0,
        pose: Any = None,
        time_s: float | None = None,
        answer_time_s: float | None = None,
    ) -> GuardReport:
        """Read an LLM's whole reply (untrusted) and validate its control signals.

        ``reply`` is a :class:`~safeembodai_core.models.BackendReply` -- or a mapping with its fields
        (``text``, ``finish_reason``, ``reasoning``, ``choices``, ``envelope_error``), or the answer
        text alone. The reading is the guarded loop's (:func:`~safeembodai_core.models.read_reply`):
        a reply that did not end with a normal stop, holds two choices, a second plan in its
        reasoning, duplicate keys, several JSON objects, text outside the object (unless the
        guard's ``limits`` allow it), huge numbers and the like gives a ``schema`` verdict. To read
        an OpenAI-style response body you received yourself, pass
        :func:`~safeembodai_core.models.chat_completion.reply_from_chat_completion` of it.
        ``lidar_mm``, ``max_range_mm``, ``pose``, ``time_s`` and ``answer_time_s`` are as for :meth:`check`.
        """
        try:
            response = read_reply(as_reply(reply), self.limits)
        except ResponseParseError as error:
            # the scan is kept for later checks all the same
            self._context(lidar_mm, max_range_mm, pose, time_s, answer_time_s)
            return GuardReport(verdicts=[Verdict(rule="schema", valid=False, reason=str(error))],
                               parse_error=str(error))
        report = self.check([s.model_dump() for s in response.control], lidar_mm=lidar_mm, max_range_mm=max_range_mm,
                            pose=pose, time_s=time_s, answer_time_s=answer_time_s)
        report.response = response
        return report

    def check_answer(
        self,
        text: str,
        *,
        finish_reason: str | None = None,
        reasoning: str | None = None,
        lidar_mm: Any = None,
        max_range_mm: float = 10_000.0,
        pose: Any = None,
        time_s: float | None = None,
    ) -> GuardReport:
        """:meth:`check_reply` of a reply given as its text, finish reason and reasoning.

        Pass the provider's ``finish_reason`` and its separate ``reasoning`` field when you have
        them: an answer that did not end with a normal stop (``"length"``, ``"content_filter"``,
        ...) is refused, and a plan in the reasoning other than the answer's is a second plan.
        """
        reply = as_reply({"text": text, "finish_reason": finish_reason, "reasoning": reasoning})
        return self.check_reply(reply, lidar_mm=lidar_mm, max_range_mm=max_range_mm, pose=pose, time_s=time_s)


def run_guarded_trial(
    environment: Environment | str | dict[str, Any],
    backend: LLMBackend | str | dict[str, Any],
    *,
    defences: Defences | dict[str, Any] | None = None,
    seed: int = 0,
    max_steps: int = 20,
    instruction: str | None = None,
    perception: Any = "images",
    prompt_builder: Any = "jinja",
    state: Any = "memory",
    attackers: Sequence[Any] = (),
    limits: ControlLimits = DEFAULT_LIMITS,
    plugins: Plugins | None = None,
    trial_id: str = "trial",
) -> tuple[TrialResult, list[StepRecord]]:
    """Run one guarded trial around your own parts; return the result and every step record.

    Validators come from ``defences.validators`` (names and options, as in a scenario) and run
    only when ``defences.safety_validation`` is on. Components named here are built as a
    scenario builds them: ``BuildContext.seed`` is ``seed`` (0 for the environment, which gets
    ``seed`` in ``reset``, and the state store, which outlives trials).
    """
    plugins = plugins or load_plugins()
    defences = defences if isinstance(defences, Defences) else Defences.model_validate(defences or {})

    def one(kind: str, item: Any, seed: int = seed) -> Any:
        return _components(plugins, kind, [item], seed)[0][1]

    parts = TrialParts(
        environment=one("environment", environment, 0),
        perception=one("perception", perception),
        prompt_builder=one("prompt_builder", prompt_builder),
        state=one("state_store", state, 0),
        backend=one("llm_backend", backend),
        validators=_components(plugins, "validator", defences.validators, seed),
        attackers=_components(plugins, "attacker", attackers, seed),
    )
    settings = LoopSettings(max_steps=max_steps, defences=defences, limits=limits,
                            instruction=instruction or DEFAULT_INSTRUCTION)
    spec = TrialSpec(trial_id=trial_id, environment=type(parts.environment).__name__, arm="custom",
                     condition="custom", seed=seed)
    result = run_trial(spec, parts, settings, plugins)
    return result, parts.state.steps(trial_id)
