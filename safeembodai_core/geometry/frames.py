"""Poses and points between frames, and a pose advanced by a motion: the one place each is computed.

A frame is given by its origin's pose in the outer frame, ``(x_mm, y_mm, heading_deg)``; x forward, y left.
"""

from __future__ import annotations

import math
from typing import TypeVar

import numpy as np

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


def into_frame(points: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    """(M, 2) points of the outer frame in the frame whose origin is ``origin``."""
    x, y, heading = origin
    rad = math.radians(heading)
    c, s = math.cos(rad), math.sin(rad)
    shifted = points - np.array([x, y])
    return np.column_stack((shifted[:, 0] * c + shifted[:, 1] * s, -shifted[:, 0] * s + shifted[:, 1] * c))


def out_of_frame(points: np.ndarray, origin: tuple[float, float, float]) -> np.ndarray:
    """(M, 2) points of the frame whose origin is ``origin`` in the outer frame (:func:`into_frame`'s inverse)."""
    x, y, heading = origin
    rad = math.radians(heading)
    c, s = math.cos(rad), math.sin(rad)
    return np.column_stack((x + points[:, 0] * c - points[:, 1] * s, y + points[:, 0] * s + points[:, 1] * c))


def compose(origin: tuple[float, float, float], pose: tuple[float, float, float]) -> tuple[float, float, float]:
    """``pose``, given in the frame whose origin is ``origin``, in the outer frame; heading wrapped to [-180, 180)."""
    (xo, yo, ho), (x, y, h) = origin, pose
    rad = math.radians(ho)
    c, s = math.cos(rad), math.sin(rad)
    return xo + x * c - y * s, yo + x * s + y * c, wrap_deg(ho + h)


def advance(pose: tuple[float, float, float], distance_mm: float = 0.0,
            turn_deg: float = 0.0) -> tuple[float, float, float]:
    """``pose`` after driving ``distance_mm`` along its heading (negative: backwards), then turning by
    ``turn_deg`` (counter-clockwise; the heading is not wrapped, so a plan's turns add up exactly)."""
    x, y, heading = pose
    if distance_mm:
        rad = math.radians(heading)
        x, y = x + distance_mm * math.cos(rad), y + distance_mm * math.sin(rad)
    return x, y, heading + turn_deg


def yaw_quaternion(yaw_deg: float) -> tuple[float, float, float, float]:
    """The rotation about z by ``yaw_deg`` as a quaternion ``(x, y, z, w)``."""
    half = math.radians(yaw_deg) / 2
    return 0.0, 0.0, math.sin(half), math.cos(half)


def quaternion_yaw_deg(x: float, y: float, z: float, w: float) -> float:
    """The heading (degrees) of a quaternion about z (roll and pitch ignored)."""
    return math.degrees(math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z)))
