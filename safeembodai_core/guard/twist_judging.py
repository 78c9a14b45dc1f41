"""A held velocity command through the guard's rules: refuse, say when, or limit the speed.

:func:`judge_twist` judges a :class:`~safeembodai_core.ros.Twist` held for a while. Rules that judge
held motions (:class:`~safeembodai_core.guard.held_motion.MotionValidator`: ``swept_body``) judge the exact
motion and say when the body would first touch something -- the **time before collision**; the
other rules judge the arc cut into the contract's signals (:func:`~safeembodai_core.ros.arc_signals`)
and, on a refusal, the longest safe hold is found by bisection. A sideways (holonomic) command has no
such signals, so a rule that only judges signals refuses it rather than pass it unjudged.

:func:`limit_twist` turns the judgement into a speed limit, as Nav2's collision monitor does with its
approach polygon: the command held for ``horizon_s`` would first touch something after
``t = safe_duration_s``, so the same path driven at ``t / horizon_s`` of the speed stays clear for the
whole horizon (Nav2's ``change_ratio = collision_time / time_before_collision``). Slow-down zones
(:class:`SlowdownZone`, Nav2's ``slowdown`` polygons) scale a command by their factor while a return
lies inside them; the smallest factor wins, as in Nav2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

from ..geometry import Motion, in_polygon, read_polygon
from .reports import LimitReport, TwistReport
from .held_motion import MotionValidator, MotionVerdict
from ..models import Verdict
from ..contracts.robot import RobotSpec
from ..ros.laser_scan import finite_number
from ..ros.twist import MAX_PIECES, Twist, arc_signals, longest_judged_s
from ..validation.context import ValidationContext, Validator, validate_plan

#: The finest ``resolution_s`` the other rules' longest safe hold is bisected to (a microsecond: no
#: controller's period is shorter, and a finer one would only bisect rounding).
MIN_RESOLUTION_S = 1e-6


@dataclass(frozen=True)
class SlowdownZone:
    """A zone around the robot (robot frame, mm) in which a return slows every command to ``factor``
    of its speed: a polygon (``polygon_mm``, like Nav2's ``slowdown`` polygon) or a band of
    ``band_mm`` all round the body. ``min_points`` returns must lie inside (Nav2's ``min_points``)."""

    factor: float
    polygon_mm: tuple[tuple[float, float], ...] | None = None
    band_mm: float | None = None
    name: str = "slowdown"
    min_points: int = 1

    def __post_init__(self) -> None:
        factor = finite_number("SlowdownZone", "factor", self.factor)
        if not 0.0 <= factor <= 1.0:
            raise ValueError(f"SlowdownZone.factor must be in [0, 1], got {self.factor!r}")
        object.__setattr__(self, "factor", factor)
        if (self.polygon_mm is None) == (self.band_mm is None):
            raise ValueError("SlowdownZone needs exactly one of polygon_mm and band_mm")
        if self.polygon_mm is not None:
            polygon = read_polygon(self.polygon_mm, "SlowdownZone.polygon_mm")
            object.__setattr__(self, "polygon_mm", tuple((float(x), float(y)) for x, y in polygon))
        else:
            band = finite_number("SlowdownZone", "band_mm", self.band_mm, "mm")
            if band <= 0:
                raise ValueError(f"SlowdownZone.band_mm must be > 0, got {self.band_mm!r}")
            object.__setattr__(self, "band_mm", band)
        if isinstance(self.min_points, bool) or not isinstance(self.min_points, int) or self.min_points < 1:
            raise ValueError(f"SlowdownZone.min_points must be an integer >= 1, got {self.min_points!r}")

    def count(self, points: np.ndarray, robot: RobotSpec) -> int:
        """How many of ``points`` (robot frame, mm) lie inside the zone."""
        if not len(points):
            return 0
        if self.polygon_mm is not None:
            return int(np.count_nonzero(in_polygon(points, np.array(self.polygon_mm))))
        band = self.band_mm if self.band_mm is not None else 0.0  # set whenever polygon_mm is not
        return int(np.count_nonzero(robot.body(band).inside(points)))


def _seconds(name: str, value: Any, positive: bool = False) -> float:
    seconds = finite_number("", name, value, "seconds")
    if seconds < 0 or (positive and seconds == 0):
        raise ValueError(f"{name} must be {'> 0' if positive else '>= 0'} seconds, got {value!r}")
    return seconds


def _resolution(value: Any) -> float:
    seconds = finite_number("", "resolution_s", value, "seconds")
    if not seconds >= MIN_RESOLUTION_S:
        raise ValueError(f"resolution_s must be at least {MIN_RESOLUTION_S:g} seconds, got {value!r}")
    return seconds


def _motion(twist: Twist, duration_s: float) -> Motion:
    """``twist`` held for ``duration_s`` as the rules' :class:`Motion` (millimetres per second), or a
    ``ValueError`` naming the Twist's field whose speed overflows in millimetres (about 1.8e305 m/s)."""
    for name, speed in (("linear.x", twist.linear_x), ("linear.y", twist.linear_y)):
        if not math.isfinite(speed * 1000.0):
            raise ValueError(f"Twist {name} = {speed:g} m/s is too fast to judge: in millimetres per second it "
                             "overflows")
    return Motion(twist.linear_x * 1000.0, twist.linear_y * 1000.0, twist.angular_z, duration_s)


def _motion_verdict(name: str, rule: MotionValidator, motion: Motion, context: ValidationContext) -> MotionVerdict:
    try:
        judged = rule.validate_motion(motion, context)
        if not isinstance(judged, MotionVerdict):
            raise TypeError(f"validate_motion returned {type(judged).__name__}, not a MotionVerdict")
    except Exception as error:  # a broken rule refuses, from the start: it never lets a command through
        return MotionVerdict(Verdict(rule=name, valid=False, reason=f"rule failed ({type(error).__name__}: {error})"))
    return MotionVerdict(judged.verdict.model_copy(update={"rule": name}), judged.contact_s, judged.contact,
                         judged.return_s, judged.unseen_s)


def judge_twist(twist: Twist, duration_s: Any, context: ValidationContext, rules: Sequence[tuple[str, Validator]],
                resolution_s: float = 0.05) -> TwistReport:
    """``twist`` held for ``duration_s`` seconds, judged by ``rules`` from ``context`` (module docstring).
    ``resolution_s`` (at least :data:`MIN_RESOLUTION_S`) is how finely the other rules' longest safe hold
    is bisected. A bad duration or resolution, or a speed too large to judge, is a ``ValueError`` naming it."""
    duration_s = _seconds("duration_s", duration_s)
    resolution_s = _resolution(resolution_s)
    motion = _motion(twist, duration_s)
    verdicts: list[Verdict] = []
    safe, contact, kind = duration_s, None, None
    firsts: dict[str, float] = {}
    pieces_rules = [(n, r) for n, r in rules if not isinstance(r, MotionValidator)]
    for name, rule in rules:
        if not isinstance(rule, MotionValidator):
            continue
        judged = _motion_verdict(name, rule, motion, context)
        verdicts.append(judged.verdict)
        if judged.contact_s is not None and (contact is None or judged.contact_s < contact):
            contact, kind = judged.contact_s, judged.contact
        for what, when in (("return", judged.return_s), ("unseen", judged.unseen_s)):
            if when is not None:
                firsts[what] = min(firsts.get(what, when), when)
        if not judged.verdict.valid:
            safe = min(safe, judged.contact_s if judged.contact_s is not None else 0.0)
    signals: list[Any] = []
    if pieces_rules and twist.linear_y != 0.0:
        safe = 0.0
        verdicts += [Verdict(rule=name, valid=False, reason=(
            "judges the contract's straights and turns only, and a sideways (holonomic) command has none; "
            "judge it with a rule that judges held motions (swept_body)")) for name, _ in pieces_rules]
    elif pieces_rules:
        longest = longest_judged_s(twist)
        signals = arc_signals(twist, min(duration_s, longest))
        piece_verdicts = validate_plan(signals, context, pieces_rules) if signals else []
        verdicts += piece_verdicts
        if duration_s > longest:  # too long an arc to judge piece by piece: refused, whatever the rest says
            verdicts.append(Verdict(rule="twist", valid=False, reason=(
                f"held {duration_s:g} s the command sweeps more than {MAX_PIECES} pieces of arc; only the first "
                f"{longest:.2f} s were judged")))
        if not all(v.valid for v in piece_verdicts) or duration_s > longest:
            low, high = 0.0, min(safe, longest)  # the longest safe hold for these rules, by bisection on the arc
            if all(v.valid for v in validate_plan(arc_signals(twist, high), context, pieces_rules)):
                low = high
            while high - low > resolution_s:
                middle = (low + high) / 2
                if not low < middle < high:  # no float between them: a hold of ~1e16 s is bisected to its ulp
                    break
                if all(v.valid for v in validate_plan(arc_signals(twist, middle), context, pieces_rules)):
                    low = middle
                else:
                    high = middle
            safe = min(safe, low)
    return TwistReport(signals=signals, verdicts=verdicts, twist=twist, duration_s=duration_s,
                       safe_duration_s=duration_s if all(v.valid for v in verdicts) else safe,
                       collision_time_s=contact, contact=kind, obstacle_time_s=firsts.get("return"),
                       unseen_time_s=firsts.get("unseen"))


def limit_twist(twist: Twist, horizon_s: Any, context: ValidationContext, rules: Sequence[tuple[str, Validator]],
                zones: Sequence[SlowdownZone] = (), resolution_s: float = 0.05) -> LimitReport:
    """The fastest command along ``twist``'s path that stays clear for ``horizon_s``, and why (module docstring)."""
    horizon_s = _seconds("horizon_s", horizon_s, positive=True)
    report = judge_twist(twist, horizon_s, context, rules, resolution_s)
    factor, reasons, held = 1.0, [], []
    if not report.valid:
        factor = max(0.0, min(1.0, report.safe_duration_s / horizon_s))
        what = "a return" if report.contact == "return" else "unseen space"
        when = (f"touches {what} after {report.collision_time_s:.2f} s" if report.collision_time_s is not None
                else f"is safe for {report.safe_duration_s:.2f} s")
        reasons.append(f"approach: held {horizon_s:g} s the command {when}; "
                       + ("stop" if factor == 0 else f"speed x{factor:.3f} keeps the path clear for the horizon"))
        reasons += report.reasons
    if zones:
        scan = context.scan
        points = context.to_planned_frame(scan.points()) if scan is not None else np.empty((0, 2))
        for zone in zones:
            inside = zone.count(points, context.robot)
            if inside >= zone.min_points:
                held.append(zone.name)
                reasons.append(f"slowdown zone {zone.name!r}: {inside} return(s) inside; speed x{zone.factor:g}")
                factor = min(factor, zone.factor)
    if not math.isfinite(factor):
        factor = 0.0
    return LimitReport(twist=twist.scaled(factor), factor=factor, requested=twist, horizon_s=horizon_s,
                       report=report, reasons=reasons, zones=held)


__all__ = ["MIN_RESOLUTION_S", "SlowdownZone", "judge_twist", "limit_twist"]
