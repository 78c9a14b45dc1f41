"""Where a plan would drive and what it would meet: a plan of straights and turns in place as the
path it drives from a pose, a scan's returns in the same frame, and the nearest return in a
straight's corridor. For pictures of plans (the Rerun export, ``view``'s trial pages), not for
judging them: the validators judge (``safeembodai_core.validation``)."""

from __future__ import annotations

import math

import numpy as np

from ..models import ControlSignal, Pose, Straight
from ..models.observation import LidarScan


def plan_path(pose: Pose, plan: list[ControlSignal]) -> tuple[np.ndarray, list[tuple[np.ndarray, np.ndarray]]]:
    """The points (mm, world frame) a plan of straights and turns in place drives from ``pose``, and
    each signal's segment (start, end; a turn's is a point)."""
    x, y, heading = pose.x_mm, pose.y_mm, pose.heading_deg
    points, segments = [np.array([x, y])], []
    for signal in plan:
        start = np.array([x, y])
        if isinstance(signal, Straight):
            rad = math.radians(heading)
            x += signal.signed_distance_mm * math.cos(rad)
            y += signal.signed_distance_mm * math.sin(rad)
            points.append(np.array([x, y]))
        else:
            heading += signal.signed_angle_deg
        segments.append((start, np.array([x, y])))
    return np.array(points), segments


def scan_points(scan: LidarScan, pose: Pose) -> np.ndarray:
    """A scan's returns (mm) in the world frame, taken at ``pose``."""
    local = scan.points()
    rad = math.radians(pose.heading_deg)
    c, s = math.cos(rad), math.sin(rad)
    return np.column_stack((pose.x_mm + local[:, 0] * c - local[:, 1] * s,
                            pose.y_mm + local[:, 0] * s + local[:, 1] * c)) if local.size else np.zeros((0, 2))


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
