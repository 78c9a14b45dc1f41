"""Safety validation machinery shared by the loop and the library API.

Validators judge one control signal at a time. A plan C_i = [g_i1, ..., g_in] is checked in
order against the robot's *planned* pose: before judging g_ij the context is advanced by the
exact motion of g_i1..g_i(j-1), and the LiDAR scan is re-projected into that pose. A rule like
the paper's V(C) therefore checks the second signal of "turn left 45, straight 300" against
the beams that will face forward after the turn, not the ones facing forward now.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Iterable, Sequence

import numpy as np

from .components import RobotSpec, Validator
from .models import DEFAULT_LIMITS, ControlLimits, ControlSignal, LidarScan, Turn, Verdict

_UNKNOWN_RAY_STEP_MM = 50.0


@dataclass(frozen=True)
class ValidationContext:
    """What a validator knows: the scan taken at the start of the step, the robot's body, the
    actuation limits, and the planned pose ``offset`` (x mm, y mm, heading deg) relative to
    the pose where the scan was taken."""

    scan: LidarScan | None
    robot: RobotSpec = RobotSpec()
    limits: ControlLimits = DEFAULT_LIMITS
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def advanced(self, signal: ControlSignal) -> "ValidationContext":
        """The context after ``signal`` is executed exactly as commanded."""
        x, y, heading = self.offset
        if isinstance(signal, Turn):
            return replace(self, offset=(x, y, heading + signal.signed_angle_deg))
        rad = math.radians(heading)
        d = signal.signed_distance_mm
        return replace(self, offset=(x + d * math.cos(rad), y + d * math.sin(rad), heading))

    def require_scan(self, rule: str) -> LidarScan:
        if self.scan is None:
            raise ValueError(f"validator {rule!r} needs a LiDAR scan and none was given")
        return self.scan

    def to_planned_frame(self, points: np.ndarray) -> np.ndarray:
        """(M, 2) points from the frame the scan was taken in to the planned robot frame."""
        x, y, heading = self.offset
        rad = math.radians(heading)
        c, s = math.cos(rad), math.sin(rad)
        shifted = points - np.array([x, y])
        return np.column_stack((shifted[:, 0] * c + shifted[:, 1] * s, -shifted[:, 0] * s + shifted[:, 1] * c))

    def to_scan_frame(self, points: np.ndarray) -> np.ndarray:
        """(M, 2) points from the planned robot frame back to the frame the scan was taken in."""
        x, y, heading = self.offset
        rad = math.radians(heading)
        c, s = math.cos(rad), math.sin(rad)
        return np.column_stack((x + points[:, 0] * c - points[:, 1] * s, y + points[:, 0] * s + points[:, 1] * c))

    def points_at_pose(self, include_free_bound: bool = True) -> np.ndarray:
        """LiDAR returns as (M, 2) points in the planned robot frame (mm)."""
        scan = self.require_scan("points_at_pose")
        return self.to_planned_frame(scan.points(include_free_bound=include_free_bound))

    def unknown_points_at_pose(self) -> np.ndarray:
        """Points sampled along every missing (``nan``) beam, in the planned robot frame.

        A missing beam says nothing about its direction, so rules treat these samples as possible
        obstacles: conservative, never optimistic.
        """
        scan = self.require_scan("unknown_points_at_pose")
        missing = np.flatnonzero(np.isnan(scan.ranges_mm))
        if missing.size == 0:
            return np.empty((0, 2))
        radii = np.arange(0.0, scan.max_range_mm + _UNKNOWN_RAY_STEP_MM, _UNKNOWN_RAY_STEP_MM)
        rad = np.radians(scan.angles_deg[missing])
        xs = np.outer(np.cos(rad), radii).ravel()
        ys = np.outer(np.sin(rad), radii).ravel()
        return self.to_planned_frame(np.column_stack((xs, ys)))

    def ranges_at_pose(self) -> np.ndarray:
        """The scan as it would read from the planned pose: ``inf`` free, ``nan`` unknown.

        At the scan's own pose this is the scan itself. After pure rotations beams are shifted,
        taking the nearer of two neighbours when the angle falls between beams. After a
        translation the returns are re-binned; a bin with no return takes the nearest of its
        neighbours within two beams, else it is unknown.
        """
        scan = self.require_scan("ranges_at_pose")
        x, y, heading = self.offset
        n, inc = scan.beam_count, scan.increment_deg
        if math.hypot(x, y) < 1e-9:
            shift = (heading / inc) % n
            low = int(math.floor(shift)) % n
            if abs(shift - round(shift)) < 1e-9:
                return np.roll(scan.ranges_mm, -int(round(shift)) % n)
            return np.minimum(np.roll(scan.ranges_mm, -low), np.roll(scan.ranges_mm, -(low + 1) % n))
        binned = np.full(n, np.inf)
        hit = np.zeros(n, dtype=bool)
        points = self.points_at_pose(include_free_bound=True)
        if points.size:
            index = np.rint(np.degrees(np.arctan2(points[:, 1], points[:, 0])) / inc).astype(int) % n
            np.minimum.at(binned, index, np.hypot(points[:, 0], points[:, 1]))
            hit[index] = True
        filled = binned.copy()
        for k in np.flatnonzero(~hit):
            neighbours = [binned[(k + d) % n] for d in (-2, -1, 1, 2) if hit[(k + d) % n]]
            filled[k] = min(neighbours) if neighbours else np.nan
        unknown = self.unknown_points_at_pose()
        if unknown.size:
            index = np.rint(np.degrees(np.arctan2(unknown[:, 1], unknown[:, 0])) / inc).astype(int) % n
            filled[index] = np.nan
        return filled


def validate_plan(
    signals: Sequence[ControlSignal],
    context: ValidationContext,
    rules: Iterable[tuple[str, Validator]],
) -> list[Verdict]:
    """Judge each signal of a plan with every rule, advancing the planned pose between signals."""
    rules = list(rules)
    verdicts: list[Verdict] = []
    for index, signal in enumerate(signals):
        for name, rule in rules:
            try:
                verdict = rule.validate(signal, context)
            except Exception as error:  # a broken rule refuses: it never lets a command through
                verdict = Verdict(rule=name, valid=False, reason=f"rule failed ({type(error).__name__}: {error})")
            if not isinstance(verdict, Verdict):
                verdict = Verdict(rule=name, valid=False, reason=f"rule returned {type(verdict).__name__}, not a Verdict")
            verdicts.append(verdict.model_copy(update={"signal_index": index, "rule": name}))
        context = context.advanced(signal)
    return verdicts


__all__ = ["ValidationContext", "validate_plan"]
