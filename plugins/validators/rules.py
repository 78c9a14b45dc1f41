"""``command_limits`` and ``lidar_clearance`` (the paper's V(C)), plus the scan checks rules share."""

from __future__ import annotations

import math

import numpy as np

from safeembodai_core.components import Validator
from safeembodai_core.models import ControlSignal, LidarScan, Straight, Turn, Verdict
from safeembodai_core.validation import ValidationContext


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


class CommandLimitsRule(Validator):
    """Distance and angle finite and strictly within (min, max), in millimetres and degrees."""

    name = "command_limits"

    def __init__(self, options) -> None:
        self.options = options

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        o = self.options
        if isinstance(signal, Straight):
            low, high = o.min_distance_mm, o.max_distance_mm or context.limits.max_distance_mm
            value, unit, what = signal.distance, "mm", "distance"
        elif isinstance(signal, Turn):
            low, high = o.min_angle_deg, o.max_angle_deg or context.limits.max_angle_deg
            value, unit, what = signal.angle, "degrees", "angle"
        else:
            return Verdict(rule=self.name, valid=False, reason=f"unknown control signal {signal!r}")
        if not math.isfinite(value) or not low < value < high:
            return Verdict(rule=self.name, valid=False,
                           reason=f"{signal.describe()}: {what} must be a number with {low:g} < {what} < {high:g} "
                                  f"({unit}); use several signals for a longer motion")
        return Verdict(rule=self.name, valid=True)


class LidarClearanceRule(Validator):
    """V(C) of the paper, evaluated from the planned pose (see ``ValidationContext``)."""

    name = "lidar_clearance"

    def __init__(self, options) -> None:
        self.options = options

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        if not isinstance(signal, Straight):
            return Verdict(rule=self.name, valid=True, reason="turns are always valid under V(C)")
        scan = checked_scan(context, self.name, self.options.expected_beams)
        r = self.options.half_angle_deg
        # dist is a clearance from the LiDAR at the robot's centre: never less than the body's radius
        dist = max(self.options.safety_distance_mm, context.robot.radius_mm)
        direction, where = direction_words(signal)
        centre = 0.0 if signal.direction == "forward" else 180.0
        beams = scan.sector(centre, r)
        if beams.size == 0:
            raise ValueError(f"{self.name}: no beam of the {scan.beam_count}-beam scan falls within ±{r:g} deg")
        sector = context.ranges_at_pose()[beams]
        if np.isnan(sector).any():
            angle = float(scan.angles_deg[beams[np.flatnonzero(np.isnan(sector))[0]]])
            return Verdict(rule=self.name, valid=False, reason=(
                f"{signal.describe()}: no LiDAR reading at {angle:.0f} deg, inside the checked ±{r:g} deg "
                f"{where}; clearance cannot be confirmed, so no {direction} motion is allowed; turn first"))
        sector = np.minimum(sector, scan.max_range_mm)  # no return: free up to the sensor's range
        worst = int(np.argmin(sector))
        nearest = float(sector[worst])
        if nearest - signal.distance >= dist:
            return Verdict(rule=self.name, valid=True)
        angle = float(scan.angles_deg[beams[worst]])
        allowed = math.floor(nearest - dist)  # rounded down: following the advice must pass
        advice = (f"going {direction}, at most {allowed} mm is safe" if allowed >= 1
                  else f"no {direction} motion is safe here; turn away first")
        return Verdict(rule=self.name, valid=False, reason=(
            f"{signal.describe()}: obstacle {nearest:.0f} mm {where} (beam at {angle:.0f} deg) would be "
            f"{nearest - signal.distance:.0f} mm away after the motion, less than the {dist:g} mm required; {advice}"))
