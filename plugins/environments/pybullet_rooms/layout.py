"""Seeded placement of the robot, the can, the soccer balls and the Labbots.

Everything is drawn from one generator in a fixed order (robot, heading, can, balls, Labbots),
so a seed gives the same room in every process. Bodies never overlap: any two keep at least
the passage gap between their surfaces (so the robot fits between them), and every body keeps
:data:`WALL_MARGIN_MM` from the walls. The can starts at least ``min_start_distance_mm`` from
the robot and outside the camera's view (its bearing more than 10 degrees beyond the edge of
the field of view), so the robot has to look for it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from safeembodai_core.errors import EnvironmentError_

from .options import CAN_RADIUS_MM, RoomOptions
from safeembodai_core.geometry.frames import wrap_deg

WALL_MARGIN_MM = 50.0
HIDDEN_MARGIN_DEG = 10.0
_LAYOUT_ATTEMPTS = 40
_BODY_ATTEMPTS = 400


@dataclass(frozen=True)
class Layout:
    """Where everything starts (world frame, millimetres; room corner at the origin)."""

    robot_xy: np.ndarray  # (2,)
    robot_heading_deg: float
    can_xy: np.ndarray  # (2,)
    balls_xy: np.ndarray  # (B, 2)
    labbots_xy: np.ndarray  # (L, 2)
    labbots_heading_deg: np.ndarray  # (L,)


def bearing_deg(origin: np.ndarray, heading_deg: float, point: np.ndarray) -> float:
    """Bearing of ``point`` seen from ``origin`` facing ``heading_deg``: CCW, in [-180, 180)."""
    angle = math.degrees(math.atan2(point[1] - origin[1], point[0] - origin[0])) - heading_deg
    return wrap_deg(angle)


def draw_layout(options: RoomOptions, rng: np.random.Generator) -> Layout:
    """A random non-overlapping layout; raises :class:`EnvironmentError_` if none is found."""
    for _ in range(_LAYOUT_ATTEMPTS):
        layout = _try_layout(options, rng)
        if layout is not None:
            return layout
    raise EnvironmentError_(
        f"could not place balls={options.ball_count} and labbots={options.labbot_count} without overlap in "
        f"room_mm={options.room_mm:g} (passage {options.passage:g} mm, min_start_distance_mm="
        f"{options.start_distance:g}); lower the counts or passage_mm, or raise room_mm")


def _uniform_xy(rng: np.random.Generator, room: float, radius: float) -> np.ndarray:
    low = radius + WALL_MARGIN_MM
    return rng.uniform(low, room - low, size=2)


def _try_layout(o: RoomOptions, rng: np.random.Generator) -> Layout | None:
    gap = o.passage
    robot = _uniform_xy(rng, o.room_mm, o.robot_radius_mm)
    heading = float(rng.uniform(-180.0, 180.0))
    can = None
    for _ in range(_BODY_ATTEMPTS):
        point = _uniform_xy(rng, o.room_mm, CAN_RADIUS_MM)
        if float(np.hypot(*(point - robot))) < max(o.start_distance, o.robot_radius_mm + CAN_RADIUS_MM + gap):
            continue
        if abs(bearing_deg(robot, heading, point)) <= o.camera_fov_deg / 2 + HIDDEN_MARGIN_DEG:
            continue
        can = point
        break
    if can is None:
        return None
    placed = [(robot, o.robot_radius_mm), (can, CAN_RADIUS_MM)]
    balls = _scatter(rng, o.room_mm, o.ball_count, o.ball_radius_mm, placed, gap)
    if balls is None:
        return None
    labbot_radius = getattr(o, "labbot_radius_mm", 0.0)
    labbots = _scatter(rng, o.room_mm, o.labbot_count, labbot_radius, placed, gap)
    if labbots is None:
        return None
    headings = rng.uniform(-180.0, 180.0, size=o.labbot_count)
    return Layout(robot, heading, can, balls, labbots, headings)


def _scatter(rng, room, count, radius, placed, gap) -> np.ndarray | None:
    """``count`` centres for discs of ``radius``, appended to ``placed``; None if they do not fit."""
    centres = []
    for _ in range(count):
        for _ in range(_BODY_ATTEMPTS):
            point = _uniform_xy(rng, room, radius)
            if all(float(np.hypot(*(point - xy))) >= radius + r + gap for xy, r in placed):
                break
        else:
            return None
        placed.append((point, radius))
        centres.append(point)
    return np.array(centres, dtype=float).reshape(count, 2)
