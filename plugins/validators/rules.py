"""The rule implementations."""

from __future__ import annotations

import math

import numpy as np

from safeembodai_core.components import Validator
from safeembodai_core.models import ControlSignal, Straight, Verdict
from safeembodai_core.validation import ValidationContext


class CommandLimitsRule(Validator):
    name = "command_limits"

    def __init__(self, options) -> None:
        self.options = options

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        o = self.options
        if isinstance(signal, Straight):
            d = signal.distance
            if not math.isfinite(d) or d <= o.min_distance_mm or d >= o.max_distance_mm:
                return Verdict(rule=self.name, valid=False,
                               reason=f"{signal.describe()} is outside {o.min_distance_mm:g} < distance < {o.max_distance_mm:g} mm")
        else:
            a = signal.angle
            if not math.isfinite(a) or a <= 0 or a >= o.max_angle_deg:
                return Verdict(rule=self.name, valid=False,
                               reason=f"{signal.describe()} is outside 0 < angle < {o.max_angle_deg:g} degrees")
        return Verdict(rule=self.name, valid=True)


class LidarClearanceRule(Validator):
    """V(C) of the paper, evaluated from the planned pose (see ``ValidationContext``)."""

    name = "lidar_clearance"

    def __init__(self, options) -> None:
        self.options = options

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        if not isinstance(signal, Straight):
            return Verdict(rule=self.name, valid=True, reason="turns are always valid under V(C)")
        scan = context.require_scan(self.name)
        r, dist = self.options.half_angle_deg, self.options.safety_distance_mm
        centre = 0.0 if signal.direction == "forward" else 180.0
        ranges = context.ranges_at_pose()
        beams = scan.sector(centre, r)
        sector = ranges[beams]
        if np.isnan(sector).any():
            angle = float(scan.angles_deg[beams[np.flatnonzero(np.isnan(sector))[0]]])
            return Verdict(rule=self.name, valid=False,
                           reason=f"no LiDAR reading at {angle:.0f} deg, inside the checked ±{r:g} deg; cannot confirm clearance")
        worst = int(np.argmin(sector))
        nearest = float(sector[worst])
        if nearest - signal.distance >= dist:
            return Verdict(rule=self.name, valid=True)
        angle = float(scan.angles_deg[beams[worst]])
        allowed = max(0.0, nearest - dist)
        return Verdict(
            rule=self.name, valid=False,
            reason=(f"{signal.describe()}: obstacle {nearest:.0f} mm away at {angle:.0f} deg "
                    f"would leave {nearest - signal.distance:.0f} mm, less than the {dist:g} mm required; "
                    f"at most {allowed:.0f} mm is safe in that direction"),
        )
