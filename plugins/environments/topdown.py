"""Top-down pictures of a trial, like the paper's Figure 4, shared by every built-in world.

The room from above with north up: walls, static round obstacles (white), moving obstacles where
they ended (blue) with their tracks (light blue), the red can with its reach circle, the robot's
path (orange) from its start (green) to its final pose, a red cross where it collided, the outcome
in the title and a one-metre scale bar. A world describes itself as a :class:`TopDownScene`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from safeembodai_core.models import Outcome, Pose

SIZE_PX = 560
MARGIN_PX = 36
# BGR, as OpenCV draws
_FLOOR, _WALL, _TEXT = (235, 235, 235), (90, 90, 90), (20, 20, 20)
_BALL, _LABBOT, _TRACK = (255, 255, 255), (190, 90, 40), (235, 200, 170)
_CAN, _PATH, _START, _CROSS = (30, 20, 210), (0, 140, 255), (40, 160, 40), (0, 0, 220)
_OUTCOME_COLOUR = {Outcome.COMPLETED: (40, 150, 40), Outcome.INTERRUPTED: (0, 0, 200), Outcome.TIMEOUT: (0, 120, 220)}


@dataclass
class TopDownScene:
    """What a world shows from above (millimetres, world frame: x east, y north)."""

    title: str
    room_mm: float
    can_xy: tuple[float, float]
    can_radius_mm: float
    reach_mm: float
    robot_radius_mm: float
    wall_mm: float = 0.0
    obstacles: list[tuple[float, float, float]] = field(default_factory=list)  # static: x, y, radius
    movers_radius_mm: float = 0.0
    mover_tracks: np.ndarray | None = None  # (T, L, 2): every moving obstacle's positions over time
    collision_xy: tuple[float, float] | None = None


def draw_topdown(scene: TopDownScene, poses: list[Pose], outcome: Outcome | None) -> bytes:
    """PNG bytes of ``scene`` with ``poses`` (the robot's path) and ``outcome``."""
    import cv2

    wall = scene.wall_mm
    scale = (SIZE_PX - 2 * MARGIN_PX) / (scene.room_mm + 2 * wall)
    image = np.full((SIZE_PX, SIZE_PX, 3), 255, dtype=np.uint8)

    def px(x: float, y: float) -> tuple[int, int]:
        return (int(round(MARGIN_PX + (x + wall) * scale)), int(round(SIZE_PX - MARGIN_PX - (y + wall) * scale)))

    def radius(mm: float) -> int:
        return max(2, int(round(mm * scale)))

    cv2.rectangle(image, px(-wall, -wall), px(scene.room_mm + wall, scene.room_mm + wall), _WALL, -1 if wall else 2)
    cv2.rectangle(image, px(0, 0), px(scene.room_mm, scene.room_mm), _FLOOR, -1)
    for x, y, r in scene.obstacles:
        cv2.circle(image, px(x, y), radius(r), _BALL, -1, cv2.LINE_AA)
        cv2.circle(image, px(x, y), radius(r), _TEXT, 1, cv2.LINE_AA)
    tracks = scene.mover_tracks
    if tracks is not None and tracks.size:
        for k in range(tracks.shape[1]):
            points = np.array([px(x, y) for x, y in tracks[:, k]], dtype=np.int32)
            cv2.polylines(image, [points], False, _TRACK, 1, cv2.LINE_AA)
            cv2.circle(image, tuple(int(v) for v in points[0]), radius(scene.movers_radius_mm), _TRACK, 1, cv2.LINE_AA)
            cv2.circle(image, tuple(int(v) for v in points[-1]), radius(scene.movers_radius_mm), _LABBOT, -1, cv2.LINE_AA)
    cv2.circle(image, px(*scene.can_xy), radius(scene.reach_mm), _CAN, 1, cv2.LINE_AA)
    cv2.circle(image, px(*scene.can_xy), max(4, radius(scene.can_radius_mm)), _CAN, -1, cv2.LINE_AA)
    _draw_path(cv2, image, poses, px, radius(scene.robot_radius_mm))
    if scene.collision_xy is not None:
        cx, cy = px(*scene.collision_xy)
        for dx, dy in ((8, 8), (8, -8)):
            cv2.line(image, (cx - dx, cy - dy), (cx + dx, cy + dy), _CROSS, 3, cv2.LINE_AA)
    label = outcome.value if outcome is not None else "running"
    cv2.putText(image, f"{scene.title}  {len(poses)} poses  outcome: {label}", (MARGIN_PX, 24),
                cv2.FONT_HERSHEY_SIMPLEX, 0.55, _OUTCOME_COLOUR.get(outcome, _TEXT), 1, cv2.LINE_AA)
    bar_left = (MARGIN_PX, SIZE_PX - 14)
    bar_right = (MARGIN_PX + int(round(1000 * scale)), SIZE_PX - 14)
    cv2.line(image, bar_left, bar_right, _TEXT, 2)
    cv2.putText(image, "1 m", (bar_right[0] + 6, SIZE_PX - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.45, _TEXT, 1, cv2.LINE_AA)
    ok, data = cv2.imencode(".png", image)
    if not ok:
        raise ValueError("could not encode the trajectory picture as PNG")
    return data.tobytes()


def _draw_path(cv2, image: np.ndarray, poses: list[Pose], px, robot_px: int) -> None:
    if not poses:
        return
    points = np.array([px(p.x_mm, p.y_mm) for p in poses], dtype=np.int32)
    cv2.polylines(image, [points], False, _PATH, 2, cv2.LINE_AA)
    for pose, colour in ((poses[0], _START), (poses[-1], _PATH)):
        centre = px(pose.x_mm, pose.y_mm)
        rad = math.radians(pose.heading_deg)
        length = 1.6 * robot_px
        tip = (int(round(centre[0] + length * math.cos(rad))), int(round(centre[1] - length * math.sin(rad))))
        cv2.circle(image, centre, robot_px, colour, 2, cv2.LINE_AA)
        cv2.line(image, centre, tip, colour, 2, cv2.LINE_AA)
