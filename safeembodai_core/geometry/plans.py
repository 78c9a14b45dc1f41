"""Where a plan would drive and what it would meet: a plan of straights and turns in place as the
path it drives from a pose, a scan's returns in the same frame, and the nearest return in a
straight's corridor. For pictures of plans (the Rerun export, ``view``'s trial pages), not for
judging them: the validators judge (``safeembodai_core.validation.context``)."""

from __future__ import annotations

import numpy as np

from ..models import ControlSignal, Pose, Straight
from ..models.observation import LidarScan
from .frames import advance, out_of_frame


def plan_path(pose: Pose, plan: list[ControlSignal]) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """The points (mm, world frame) a plan of straights and turns in place drives from ``pose``, and
    each signal's segment (start, end; a turn's is a point)."""
    at = (pose.x_mm, pose.y_mm, pose.heading_deg)
    points, segments = [np.array(at[:2])], []
    for signal in plan:
        start = np.array(at[:2])
        if isinstance(signal, Straight):
            at = advance(at, signal.signed_distance_mm)
            points.append(np.array(at[:2]))
        else:
            at = advance(at, turn_deg=signal.signed_angle_deg)
        segments.append((start, np.array(at[:2])))
    return np.array(points), segments


def scan_points(scan: LidarScan, pose: Pose) -> np.ndarray:
    """A scan's returns (mm) in the world frame, taken at ``pose``."""
    local = scan.points()
    return out_of_frame(local, (pose.x_mm, pose.y_mm, pose.heading_deg)) if local.size else np.zeros((0, 2))


def nearest_ahead(points: np.ndarray, start: np.ndarray, end: np.ndarray, half_width_mm: float) -> np.ndarray | None:
    """The point of ``points`` nearest ``start`` in the corridor ``half_width_mm`` either side of the
    straight from ``start`` towards ``end``, from ``start`` on (beyond ``end`` too: what a rule that keeps a
    clearance sees); None if none."""
    if points.size == 0:
        return None
    direction = end - start
    length = float(np.hypot(*direction))
    if length == 0:
        return None
    unit = direction / length
    along = (points - start) @ unit
    across = np.abs((points - start) @ np.array([-unit[1], unit[0]]))
    inside = (along >= 0) & (across <= half_width_mm)
    if not inside.any():
        return None
    candidates = points[inside]
    return candidates[np.argmin(along[inside])]
