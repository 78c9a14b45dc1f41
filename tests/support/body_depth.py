"""How deep a point lies in a robot's body, read apart from the guard.

For the tests that hold the guard's rule for a body already on a return -- only a motion that takes
the body deeper over it is refused -- to an outside reading. A body is a Nav2 shape
(:class:`nav2_reference.Shape`, metres); a point's depth is its distance to the outline, its sign
from Nav2's own point-in-polygon test (a disc's from its distance to the centre). Poses are the exact
arc's (``Motion.pose_at``), sampled.
"""

from __future__ import annotations

import math
from typing import Sequence

import numpy as np

import nav2_reference as nav2


def depth(shape: nav2.Shape, points: Sequence[tuple[float, float]]) -> np.ndarray:
    """Per point (metres, the body's frame): its distance to the shape's outline, positive inside."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if shape.radius is not None:
        return shape.radius - np.hypot(p[:, 0], p[:, 1])
    a = np.asarray(shape.polygon, dtype=float)
    edge = np.roll(a, -1, axis=0) - a
    rel = p[:, None, :] - a[None]
    t = np.clip(np.sum(rel * edge, axis=2) / np.sum(edge * edge, axis=1), 0.0, 1.0)
    near = rel - t[..., None] * edge
    distance = np.min(np.hypot(near[..., 0], near[..., 1]), axis=1)
    inside = np.array([nav2.is_point_inside_polygon(x, y, shape.polygon) for x, y in p])
    return np.where(inside, distance, -distance)


def seen_from_body(motion, t: float, points: np.ndarray) -> np.ndarray:
    """``points`` (metres, the start frame) as the body sees them after ``t`` seconds of ``motion``
    (a ``Motion``, millimetres)."""
    x, y, heading = motion.pose_at(t)
    c, s = math.cos(heading), math.sin(heading)
    rel = points - np.array([x, y]) / 1000.0
    return np.column_stack((c * rel[:, 0] + s * rel[:, 1], c * rel[:, 1] - s * rel[:, 0]))


def first_deeper(shape: nav2.Shape, points: Sequence[tuple[float, float]], motion, until_s: float, steps: int,
                 slack_m: float, endpoint: bool = True) -> float:
    """The first of ``steps`` evenly spaced times over ``[0, until_s]`` at which the moving shape holds
    one of ``points`` (metres, the start frame) more than ``slack_m`` deeper than it held it at the
    start, or than its outline when it started outside; -1 when none (Nav2's convention)."""
    p = np.asarray(points, dtype=float).reshape(-1, 2)
    if not len(p):
        return -1.0
    bar = np.maximum(depth(shape, p), 0.0) + slack_m
    for t in np.linspace(0.0, until_s, steps, endpoint=endpoint):
        if np.any(depth(shape, seen_from_body(motion, float(t), p)) > bar):
            return float(t)
    return -1.0
