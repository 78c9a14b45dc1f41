"""A faithful Python reading of Nav2's collision monitor, for the guard's conformance tests only.

Ported line by line from ros-navigation/navigation2 at commit a3a97043 (2026-08-21),
``nav2_collision_monitor``; each function names the lines it follows. Nothing here is used by the
project's code: it is the outside reference the guard is compared with (tests/core/ros/test_nav2_conformance.py).
Units are Nav2's: metres, seconds, radians. Nav2 keeps its numbers in ``double`` and Python's float
is a double, so the arithmetic (including the loop's accumulated ``time += dt``) is the same.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

NAV2_COMMIT = "a3a97043ee93d92fe8d70ec56d183933169beb1c"

Point = tuple[float, float]


@dataclass
class Pose:
    x: float = 0.0
    y: float = 0.0
    theta: float = 0.0


@dataclass
class Velocity:
    x: float
    y: float
    tw: float

    def __mul__(self, k: float) -> "Velocity":
        return Velocity(self.x * k, self.y * k, self.tw * k)


def transform_points(pose: Pose, points: Sequence[Point]) -> list[Point]:
    """src/kinematics.cpp:22-42 (``transformPoints``): p' = Rt * (p - pose)."""
    c, s = math.cos(pose.theta), math.sin(pose.theta)
    out = []
    for x, y in points:
        mx, my = x - pose.x, y - pose.y
        out.append((mx * c + my * s, -mx * s + my * c))
    return out


def project_state(dt: float, pose: Pose, vel: Velocity) -> None:
    """src/kinematics.cpp:44-66 (``projectState``): the pose moves by vel * dt, then pose and velocity
    turn by tw * dt (the velocity is kept in the initial frame and rotated each step)."""
    theta = vel.tw * dt
    c, s = math.cos(theta), math.sin(theta)
    pose.x = pose.x + vel.x * dt
    pose.y = pose.y + vel.y * dt
    pose.theta = pose.theta + theta
    vx = vel.x * c - vel.y * s
    vy = vel.x * s + vel.y * c
    vel.x, vel.y = vx, vy


def is_point_inside_polygon(px: float, py: float, polygon: Sequence[Point]) -> bool:
    """nav2_util/include/nav2_util/geometry_utils.hpp:200-233 (``isPointInsidePolygon``, ray crossings)."""
    n = len(polygon)
    res = False
    i = n - 1
    for j in range(n):
        if (py <= polygon[i][1]) == (py > polygon[j][1]):
            x_inter = polygon[i][0] + (py - polygon[i][1]) * (polygon[j][0] - polygon[i][0]) / (
                polygon[j][1] - polygon[i][1])
            if x_inter > px:
                res = not res
        i = j
    return res


@dataclass
class Shape:
    """A Nav2 polygon (``polygon`` vertices) or circle (``radius``), with its approach parameters."""

    polygon: Sequence[Point] | None = None
    radius: float | None = None
    time_before_collision: float = 1.0
    simulation_time_step: float = 0.01
    min_points: int = 2

    def points_inside(self, points: Sequence[Point]) -> int:
        """src/polygon.cpp:293-305 (``Polygon::getPointsInside``); src/circle.cpp:52-65 for a circle
        (strictly inside: ``x*x + y*y < radius_squared``)."""
        if self.radius is not None:
            r2 = self.radius * self.radius
            return sum(1 for x, y in points if x * x + y * y < r2)
        return sum(1 for x, y in points if is_point_inside_polygon(x, y, self.polygon))


def collision_time(shape: Shape, points: Sequence[Point], velocity: Velocity) -> float:
    """src/polygon.cpp:339-388 (``Polygon::getCollisionTime``): 0 when ``min_points`` are inside
    already; else simulate the held velocity in steps of ``simulation_time_step`` while ``time <=
    time_before_collision`` and return the step's start time when the projected footprint holds
    ``min_points``; -1 for no collision."""
    pose = Pose()
    vel = Velocity(velocity.x, velocity.y, velocity.tw)
    if shape.points_inside(points) >= shape.min_points:
        return 0.0
    time = 0.0
    while time <= shape.time_before_collision:
        project_state(shape.simulation_time_step, pose, vel)
        if shape.points_inside(transform_points(pose, points)) >= shape.min_points:
            return time
        time += shape.simulation_time_step
    return -1.0


def approach(shape: Shape, points: Sequence[Point], velocity: Velocity) -> Velocity | None:
    """src/collision_monitor_node.cpp:608-637 (``processApproach``): the velocity scaled by
    collision_time / time_before_collision, or None when no collision is found."""
    t = collision_time(shape, points, velocity)
    if t < 0.0:
        return None
    return velocity * (t / shape.time_before_collision)


def scan_points(angle_min: float, angle_increment: float, ranges: Sequence[float], range_min: float,
                range_max: float) -> list[Point]:
    """src/scan.cpp:92-106 (``Scan::getSourceData``) with the source frame at the base: a range in
    [range_min, range_max] is a point; anything else (NaN, inf, out of span) is no point at all.
    The angle accumulates in ``float``, as there."""
    import numpy as np

    out = []
    angle = np.float32(angle_min)
    for r in ranges:
        if range_min <= r <= range_max:
            out.append((r * math.cos(float(angle)), r * math.sin(float(angle))))
        angle = np.float32(angle + np.float32(angle_increment))
    return out


def range_points(distance: float, field_of_view: float, obstacles_angle: float) -> list[Point]:
    """src/range.cpp:115-140 (``Range::getSourceData``) with the source frame at the base: points on
    the arc of ``field_of_view`` every ``obstacles_angle``, and one at +fov/2. ``float`` angles, as there."""
    import numpy as np

    out = []
    angle = np.float32(-field_of_view / 2)
    while angle < np.float32(field_of_view / 2):
        out.append((distance * math.cos(float(angle)), distance * math.sin(float(angle))))
        angle = np.float32(angle + np.float32(obstacles_angle))
    half = float(np.float32(field_of_view / 2))
    out.append((distance * math.cos(half), distance * math.sin(half)))
    return out
