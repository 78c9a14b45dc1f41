"""``footprint_sweep``: the area the robot's body sweeps must hold no LiDAR point.

In the planned robot frame (x forward, y left, origin at the body's centre), a ``straight`` of
distance d sweeps the corridor

    forward:  0 < x < d + L/2 + front_margin,   |y| <= W/2 + margin
    backward: -(d + L/2 + front_margin) < x < 0, |y| <= W/2 + margin

(W, L: the robot's width and length). Points beside or behind the centre, outside that corridor,
never come closer during the motion, so they cannot be hit. Every LiDAR return counts, whatever
its bearing: an obstacle at 40 deg that the paper's ±30 deg sector misses is still inside the
corridor if it lies within the robot's width. A beam without a return (``inf``) counts as free up
to the sensor's range (its end is a point); a beam without a reading (``nan``) counts as an
obstacle anywhere along it beyond the body (beyond the inscribed radius min(W, L)/2). A ``turn``
in place sweeps the circle of the robot's ``radius_mm``; with ``check_turns`` a return inside it
(plus ``turn_margin_mm``) refuses the turn.
"""

from __future__ import annotations

import math

import numpy as np

from safeembodai_core.contracts.components import Validator
from safeembodai_core.models import Advice, ControlSignal, Straight, Verdict
from safeembodai_core.validation.context import ValidationContext

from .rules import checked_scan, direction_words

_AHEAD_EPS_MM = 1e-6
_SAMPLE_MM = 20.0  # corridor sampling step for the visibility check


class FootprintSweepRule(Validator):
    """Refuses a motion whose swept footprint (plus margins) holds a LiDAR point."""

    name = "footprint_sweep"

    def __init__(self, options) -> None:
        self.options = options

    def _obstacles(self, context: ValidationContext, inscribed_mm: float) -> tuple[np.ndarray, np.ndarray]:
        """Known returns, and samples along unreadable beams beyond the body, in the planned frame."""
        known = context.points_at_pose(include_free_bound=True)
        unknown = context.unknown_points_at_pose()
        if unknown.size:
            origin = context.to_planned_frame(np.zeros((1, 2)))[0]  # where the scan was taken
            unknown = unknown[np.hypot(*(unknown - origin).T) >= inscribed_mm]
        return known, unknown

    @staticmethod
    def _first_hidden(context: ValidationContext, half: float, reach: float,
                      sign: float) -> tuple[float, np.ndarray] | None:
        """The nearest corridor sample the scan never saw, as (distance along, point), if any.

        From the scan's own pose every corridor sample is on a beam that either reaches it or
        returns a point inside the corridor first, so only planned poses away from it need this.
        """
        x, y, _ = context.offset
        if math.hypot(x, y) < 1e-9:
            return None
        along = np.arange(_SAMPLE_MM, reach, _SAMPLE_MM)
        lateral = np.linspace(-half, half, max(2, int(math.ceil(2 * half / _SAMPLE_MM)) + 1))
        grid_x, grid_y = np.meshgrid(along, lateral, indexing="ij")
        planned = np.column_stack((sign * grid_x.ravel(), grid_y.ravel()))
        at_scan = context.to_scan_frame(planned)
        scan = context.scan
        assert scan is not None  # validate() ran checked_scan before any straight gets here
        ranges = np.where(np.isposinf(scan.ranges_mm), scan.max_range_mm, scan.ranges_mm)
        n, inc = scan.beam_count, scan.increment_deg
        beam = np.rint(np.degrees(np.arctan2(at_scan[:, 1], at_scan[:, 0])) / inc).astype(int) % n
        # the nearer of the neighbouring beams; a missing reading (nan) leaves the sample unseen
        seen = np.minimum(ranges[beam], np.minimum(ranges[(beam - 1) % n], ranges[(beam + 1) % n]))
        hidden = ~(np.hypot(at_scan[:, 0], at_scan[:, 1]) <= seen)  # nan (no reading) is hidden too
        if not hidden.any():
            return None
        k = np.flatnonzero(hidden)[np.argmin(np.abs(planned[hidden, 0]))]
        return float(abs(planned[k, 0])), planned[k]

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        o = self.options
        checked_scan(context, self.name, o.expected_beams)
        robot = context.robot
        width = o.width_mm or robot.width_mm
        length = o.length_mm or robot.length_mm
        known, unknown = self._obstacles(context, min(width, length) / 2)
        if isinstance(signal, Straight):
            return self._straight(signal, context, known, unknown, width, length)
        if not o.check_turns:
            return Verdict(rule=self.name, valid=True)
        return self._turn(signal, known, unknown, robot.radius_mm + o.turn_margin_mm)

    def _straight(self, signal: Straight, context: ValidationContext, known: np.ndarray, unknown: np.ndarray,
                  width: float, length: float) -> Verdict:
        o = self.options
        front = o.front_margin_mm if o.front_margin_mm is not None else o.margin_mm
        half = width / 2 + o.margin_mm
        reach = signal.distance + length / 2 + front
        sign = 1.0 if signal.direction == "forward" else -1.0
        direction, where = direction_words(signal)
        nearest: tuple[float, np.ndarray, str] | None = None
        for points, kind in ((known, "obstacle"), (unknown, "unread")):
            if not points.size:
                continue
            along_each = points[:, 0] * sign
            inside = (along_each > _AHEAD_EPS_MM) & (along_each < reach) & (np.abs(points[:, 1]) <= half)
            if inside.any():
                k = np.flatnonzero(inside)[np.argmin(along_each[inside])]
                if nearest is None or along_each[k] < nearest[0]:
                    nearest = (float(along_each[k]), points[k], kind)
        hidden = self._first_hidden(context, half, reach, sign)
        if hidden is not None and (nearest is None or hidden[0] < nearest[0]):
            nearest = (hidden[0], hidden[1], "hidden")
        if nearest is None:
            return Verdict(rule=self.name, valid=True)
        along, point, kind = nearest
        lateral = float(point[1])
        side = "left" if lateral > 0 else "right"
        other = "right" if lateral > 0 else "left"
        safe = math.floor(along - length / 2 - front)  # rounded down: following the advice must pass
        advice = (f"going {direction}, at most {safe} mm is safe" if safe >= 1
                  else f"no {direction} motion is safe here; turn away (to the {other}) first")
        offered = Advice(safe_mm=safe) if safe >= 1 else None
        path = f"the robot's path ({width:g} mm wide + {o.margin_mm:g} mm margin each side)"
        if kind == "hidden":
            what = (f"the part of {path} beyond {along:.0f} mm {where} was hidden from the LiDAR (behind something "
                    f"it saw from where the scan was taken), so it cannot be confirmed clear")
        elif kind == "unread":
            bearing = math.degrees(math.atan2(point[1], point[0]))
            what = (f"the LiDAR has no reading towards {bearing:.0f} deg, so {path} cannot be confirmed clear "
                    f"beyond {along:.0f} mm {where}")
        else:
            what = (f"obstacle {along:.0f} mm {where} and {abs(lateral):.0f} mm {side} of centre, inside {path}")
        reason = f"{signal.describe()}: {what}; {advice}"
        return Verdict(rule=self.name, valid=False, reason=reason,  # the advice's words end the reason
                       advice=offered.model_copy(update={"words_end": len(reason)}) if offered else None)

    def _turn(self, signal: ControlSignal, known: np.ndarray, unknown: np.ndarray, radius: float) -> Verdict:
        for points, is_unknown in ((known, False), (unknown, True)):
            if not points.size:
                continue
            distance = np.hypot(points[:, 0], points[:, 1])
            inside = distance < radius
            if inside.any():
                k = np.flatnonzero(inside)[np.argmin(distance[inside])]
                bearing = math.degrees(math.atan2(points[k, 1], points[k, 0]))
                what = "an unread LiDAR direction" if is_unknown else "an obstacle"
                return Verdict(rule=self.name, valid=False, reason=(
                    f"{signal.describe()}: {what} {distance[k]:.0f} mm from the robot's centre at {bearing:.0f} deg "
                    f"lies inside the circle the body sweeps when turning (radius {radius:.0f} mm); "
                    f"move straight away from it before turning"))
        return Verdict(rule=self.name, valid=True)
