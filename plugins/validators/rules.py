"""``command_limits`` and ``lidar_clearance`` (the paper's V(C)), plus the scan checks rules share."""

from __future__ import annotations

import math

import numpy as np

from safeembodai_core.contracts.components import Validator
from safeembodai_core.geometry import Motion
from safeembodai_core.guard.held_motion import MotionValidator, MotionVerdict
from safeembodai_core.models import Advice, ControlSignal, LidarScan, Straight, Turn, Verdict
from safeembodai_core.models.control import HARD_MAX_ANGLE_DEG, HARD_MAX_DISTANCE_MM
from safeembodai_core.ros.twist import piece_count
from safeembodai_core.validation.context import ValidationContext

from .options import DEFAULT_SAFETY_DISTANCE_MM


def checked_scan(context: ValidationContext, rule: str, expected_beams: int | None = None) -> LidarScan:
    """The context's scan, or a ``ValueError`` naming ``rule`` when it is missing or malformed.

    The loop turns the error into a refusing verdict: a motion that cannot be checked never runs.
    """
    scan = context.scan
    if scan is None:
        raise ValueError(f"{rule}: needs a LiDAR scan and the observation has none")
    ranges = np.asarray(scan.ranges_mm)
    if ranges.ndim != 1 or ranges.size < 4:
        raise ValueError(f"{rule}: LiDAR scan has shape {ranges.shape}; expected a 1-D array of at least 4 beams")
    if not np.issubdtype(ranges.dtype, np.number):
        raise ValueError(f"{rule}: LiDAR ranges have dtype {ranges.dtype}; expected numbers (mm)")
    if expected_beams is not None and ranges.size != expected_beams:
        raise ValueError(f"{rule}: LiDAR scan has {ranges.size} beams; this rule expects {expected_beams}")
    finite = ranges[np.isfinite(ranges)]
    if (finite.size and finite.min() < 0) or np.isneginf(ranges).any():
        raise ValueError(f"{rule}: LiDAR scan has negative ranges")
    return scan


def direction_words(signal: Straight) -> tuple[str, str]:
    """("forward", "ahead") or ("backward", "behind")."""
    return ("forward", "ahead") if signal.direction == "forward" else ("backward", "behind")


class CommandLimitsRule(MotionValidator):
    """Distance and angle finite and strictly within (min, max), in millimetres and degrees.

    Unset maxima follow the scenario's ``limits``; with ``limits.enforce: false`` (bounds as prompt
    text only) they are the hard caps, which hold inclusively: 10 m and 360 degrees. A held
    velocity is judged as the pieces :func:`~safeembodai_core.ros.arc_signals` cuts it into (at
    most 50 mm and 5 degrees each), sideways ones too; it never says a time of contact.
    """

    name = "command_limits"

    def __init__(self, options) -> None:
        self.options = options

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        o, limits = self.options, context.limits
        if isinstance(signal, Straight):
            low, own, bound, cap = o.min_distance_mm, o.max_distance_mm, limits.max_distance_mm, HARD_MAX_DISTANCE_MM
            value, unit, what = signal.distance, "mm", "distance"
        elif isinstance(signal, Turn):
            low, own, bound, cap = o.min_angle_deg, o.max_angle_deg, limits.max_angle_deg, HARD_MAX_ANGLE_DEG
            value, unit, what = signal.angle, "degrees", "angle"
        else:
            return Verdict(rule=self.name, valid=False, reason=f"unknown control signal {signal!r}")
        high = own or (bound if limits.enforce else None)
        if high is None:  # the bounds are prompt text only: the hard cap still holds
            if not math.isfinite(value) or not low < value <= cap:
                return Verdict(rule=self.name, valid=False,
                               reason=f"{signal.describe()}: {what} must be a number with {low:g} < {what} <= {cap:g} "
                                      f"({unit}, the hard cap)")
            return Verdict(rule=self.name, valid=True)
        if not math.isfinite(value) or not low < value < high:
            return Verdict(rule=self.name, valid=False,
                           reason=f"{signal.describe()}: {what} must be a number with {low:g} < {what} < {high:g} "
                                  f"({unit}); use several signals for a longer motion")
        return Verdict(rule=self.name, valid=True)

    def validate_motion(self, motion: Motion, context: ValidationContext) -> MotionVerdict:
        distance = motion.centre_travel_mm
        angle = math.degrees(abs(motion.w_rad_s) * motion.duration_s)
        try:
            pieces = piece_count(distance, angle)
        except ValueError as error:
            return MotionVerdict(Verdict(rule=self.name, valid=False, reason=f"the held command: {error}"))
        signals: list[ControlSignal] = []
        if distance / pieces > 1e-9:
            signals.append(Straight(command="straight", direction="forward", distance=distance / pieces))
        if angle / pieces > 1e-9:
            signals.append(Turn(command="turn", direction="left", angle=angle / pieces))
        for signal in signals:
            verdict = self.validate(signal, context)
            if not verdict.valid:
                reason = f"each piece of the held command: {verdict.reason}"
                return MotionVerdict(verdict.model_copy(update={"reason": reason}))
        return MotionVerdict(Verdict(rule=self.name, valid=True))


class LidarClearanceRule(Validator):
    """V(C) of the paper, evaluated from the planned pose (see ``ValidationContext``).

    At the scan's position (the plan has only turned so far) this is the paper's inequality over
    the beams within ±r of the direction of travel. After a translation it is the same inequality
    over the measured points whose bearing from the planned pose lies within ±r, with distances
    from the planned pose (``ValidationContext.nearest_in_sector``): no beam is re-binned, so a
    direction is unknown only where the sensor gave no reading.
    """

    name = "lidar_clearance"

    def __init__(self, options) -> None:
        self.options = options

    def required_mm(self, robot) -> tuple[float, str]:
        """The clearance from the LiDAR a straight must leave, and how it was set (for reasons).

        Raises ``ValueError`` when ``measured_from: lidar`` puts it inside the body without
        ``allow_below_radius``: the robot's radius is known only once an environment supplies it.
        """
        o = self.options
        if o.safety_distance_mm is None:
            return max(DEFAULT_SAFETY_DISTANCE_MM, robot.radius_mm), ""
        if o.measured_from == "body":
            return o.safety_distance_mm + robot.radius_mm, (
                f" ({o.safety_distance_mm:g} mm from the body + the robot's {robot.radius_mm:g} mm radius)")
        if o.safety_distance_mm < robot.radius_mm and not o.allow_below_radius:
            raise ValueError(
                f"{self.name}: safety_distance_mm {o.safety_distance_mm:g} is measured from the LiDAR "
                f"(measured_from: lidar) and is less than the robot's radius ({robot.radius_mm:g} mm), so the rule "
                f"would accept motions that end with an obstacle inside the body; raise it to at least "
                f"{robot.radius_mm:g}, use measured_from: body, or set allow_below_radius: true to mean it")
        return o.safety_distance_mm, ""

    def _turn(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        """``turns: ahead`` (the authors' release): a turn is refused when a beam within ±r of the
        heading it starts from reads less than dist (eyesimLLM ``action.py:55-63``, a turn's distance 0)."""
        scan = checked_scan(context, self.name, self.options.expected_beams)
        try:
            dist, how = self.required_mm(context.robot)
        except ValueError as error:
            return Verdict(rule=self.name, valid=False, reason=str(error))
        r = self.options.half_angle_deg
        reading = context.nearest_in_sector(0.0, r)
        later = "" if context.at_scan_position else " of where the plan's earlier signals leave the robot"
        if reading is None:
            return Verdict(rule=self.name, valid=False, reason=(
                f"{signal.describe()}: the {scan.beam_count}-beam LiDAR scan has no point within ±{r:g} deg "
                f"ahead{later}; clearance cannot be confirmed, so no turn is allowed (turns are checked ahead)"))
        if reading.distance_mm >= dist:
            return Verdict(rule=self.name, valid=True)
        thing = "no LiDAR reading" if reading.kind == "unread" else f"obstacle {reading.distance_mm:.0f} mm"
        return Verdict(rule=self.name, valid=False, reason=(
            f"{signal.describe()}: {thing} ahead{later} (at {reading.bearing_deg:.0f} deg), within the {dist:g} mm "
            f"required{how} before turning (turns are checked ahead); move backward first"))

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        if not isinstance(signal, Straight):
            if self.options.turns == "ahead" and isinstance(signal, Turn):
                return self._turn(signal, context)
            return Verdict(rule=self.name, valid=True, reason="turns are always valid under V(C)")
        scan = checked_scan(context, self.name, self.options.expected_beams)
        try:
            dist, how = self.required_mm(context.robot)
        except ValueError as error:  # a setting that contradicts the robot refuses, never runs silently
            return Verdict(rule=self.name, valid=False, reason=str(error))
        r = self.options.half_angle_deg
        direction, where = direction_words(signal)
        reading = context.nearest_in_sector(0.0 if signal.direction == "forward" else 180.0, r)
        later = "" if context.at_scan_position else " of where the plan's earlier signals leave the robot"
        if reading is None:
            return Verdict(rule=self.name, valid=False, reason=(
                f"{signal.describe()}: the {scan.beam_count}-beam LiDAR scan has no point within ±{r:g} deg "
                f"{where}{later}; clearance cannot be confirmed, so no {direction} motion is allowed; turn first"))
        nearest, angle = reading.distance_mm, reading.bearing_deg
        if nearest - signal.distance >= dist:
            return Verdict(rule=self.name, valid=True)
        allowed = math.floor(nearest - dist)  # rounded down: following the advice must pass
        advice = (f"going {direction}, at most {allowed} mm is safe" if allowed >= 1
                  else f"no {direction} motion is safe here; turn away first")
        offered = Advice(safe_mm=allowed) if allowed >= 1 else None
        if reading.kind == "unread" and context.at_scan_position:
            what = (f"no LiDAR reading at {angle:.0f} deg, inside the checked ±{r:g} deg {where}; "
                    f"clearance cannot be confirmed, so no {direction} motion is allowed")
            advice, offered = "turn first", None
        elif reading.kind == "unread":
            what = (f"the LiDAR has no reading of the direction {angle:.0f} deg, {nearest:.0f} mm {where}{later}, "
                    f"which would be {nearest - signal.distance:.0f} mm away after the motion, less than the "
                    f"{dist:g} mm required{how}")
        else:
            thing = ("obstacle" if reading.kind == "return"
                     else f"the end of the LiDAR's range ({scan.max_range_mm:g} mm from where the scan was taken)")
            beam = "beam at" if context.at_scan_position else "at"
            what = (f"{thing} {nearest:.0f} mm {where}{later} ({beam} {angle:.0f} deg) would be "
                    f"{nearest - signal.distance:.0f} mm away after the motion, "
                    f"less than the {dist:g} mm required{how}")
        reason = f"{signal.describe()}: {what}; {advice}"
        return Verdict(rule=self.name, valid=False, reason=reason,  # the advice's words end the reason
                       advice=offered.model_copy(update={"words_end": len(reason)}) if offered else None)
