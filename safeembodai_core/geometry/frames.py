"""Poses between frames: where the robot is now, in the frame a scan was taken in."""

from __future__ import annotations

import math
from typing import TypeVar

Angle = TypeVar("Angle")


def wrap_deg(angle: Angle) -> Angle:
    """``angle`` in degrees (a number or a numpy array) wrapped to [-180, 180): the one place it is done."""
    return (angle + 180.0) % 360.0 - 180.0  # type: ignore[operator,return-value]


def relative_pose(origin: tuple[float, float, float], pose: tuple[float, float, float]) -> tuple[float, float, float]:
    """``pose`` (x_mm, y_mm, heading_deg in one map frame) in the robot frame of ``origin`` (the same
    kind of pose): x forward, y left, the heading's difference wrapped to [-180, 180)."""
    (xo, yo, ho), (x, y, h) = origin, pose
    c, s = math.cos(math.radians(ho)), math.sin(math.radians(ho))
    dx, dy = x - xo, y - yo
    return dx * c + dy * s, -dx * s + dy * c, wrap_deg(h - ho)
