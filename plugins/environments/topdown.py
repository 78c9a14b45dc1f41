"""Top-down pictures of a trial, like the paper's Figure 4, shared by every built-in world.

The room from above with north up: walls, static round obstacles (white), moving obstacles where
they ended (blue) with their tracks (light blue), the red can with its reach circle, the robot's
path (orange) from its start (green) to its final pose, a red cross where it collided, the outcome
in the title and a one-metre scale bar. A world describes itself as a :class:`TopDownScene`.

Below the room a key (:func:`key_entries`) names each kind of mark the picture holds; the room keeps
its place in the top ``SIZE_PX`` x ``SIZE_PX`` square, the key adds ``key_height(scene)`` rows.
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
_KEY_ROW_PX, _KEY_FONT, _KEY_GAP_PX, _SWATCH_PX = 20, 0.42, 16, 22
_OUTCOME_COLOUR: dict[Outcome | None, tuple[int, int, int]] = {
    Outcome.COMPLETED: (40, 150, 40), Outcome.INTERRUPTED: (0, 0, 200), Outcome.TIMEOUT: (0, 120, 220)}


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
    obstacle_label: str = "obstacle"  # what the static obstacles are, in the key


def key_entries(scene: TopDownScene) -> list[tuple[str, str]]:
    """The key's entries, (mark, label), for the marks ``scene`` can hold: robot, start, target,
    obstacles, moving obstacles (Labbots) and their tracks, a collision."""
    entries = [("path", "robot's path"), ("start", "start"), ("robot", "robot at the end"),
               ("can", "can (target), reach circle")]
    if scene.obstacles:
        entries.append(("obstacle", scene.obstacle_label))
    if scene.mover_tracks is not None and scene.mover_tracks.size:
        entries += [("labbot", "Labbot at the end"), ("track", "Labbot track")]
    if scene.collision_xy is not None:
        entries.append(("collision", "collision"))
    return entries


def _key_rows(cv2, entries: list[tuple[str, str]]) -> list[list[tuple[str, str, int]]]:
    """The entries laid out in rows across the picture: (mark, label, width in pixels)."""
    rows: list[list[tuple[str, str, int]]] = [[]]
    used = 0
    for mark, label in entries:
        width = _SWATCH_PX + 6 + cv2.getTextSize(label, cv2.FONT_HERSHEY_SIMPLEX, _KEY_FONT, 1)[0][0]
        if rows[-1] and used + _KEY_GAP_PX + width > SIZE_PX - 2 * MARGIN_PX:
            rows.append([])
            used = 0
        used += (_KEY_GAP_PX if rows[-1] else 0) + width
        rows[-1].append((mark, label, width))
    return rows


def key_height(scene: TopDownScene) -> int:
    """Rows the key adds below the room's square."""
    import cv2

    return len(_key_rows(cv2, key_entries(scene))) * _KEY_ROW_PX + 8


def _draw_key(cv2, image: np.ndarray, scene: TopDownScene) -> None:
    """Each entry of :func:`key_entries`: its mark as drawn on the room, then its label."""
    for r, row in enumerate(_key_rows(cv2, key_entries(scene))):
        x, y = MARGIN_PX, SIZE_PX + 4 + r * _KEY_ROW_PX + _KEY_ROW_PX // 2
        for mark, label, width in row:
            _draw_mark(cv2, image, mark, (x + _SWATCH_PX // 2, y))
            cv2.putText(image, label, (x + _SWATCH_PX + 6, y + 5), cv2.FONT_HERSHEY_SIMPLEX, _KEY_FONT, _TEXT, 1,
                        cv2.LINE_AA)
            x += width + _KEY_GAP_PX


def _draw_mark(cv2, image: np.ndarray, mark: str, centre: tuple[int, int]) -> None:
    cx, cy = centre
    if mark in ("path", "track"):
        cv2.line(image, (cx - 10, cy), (cx + 10, cy), _PATH if mark == "path" else _TRACK, 2, cv2.LINE_AA)
    elif mark in ("start", "robot"):
        cv2.circle(image, centre, 6, _START if mark == "start" else _PATH, 2, cv2.LINE_AA)
        cv2.line(image, centre, (cx + 10, cy), _START if mark == "start" else _PATH, 2, cv2.LINE_AA)
    elif mark == "can":
        cv2.circle(image, centre, 8, _CAN, 1, cv2.LINE_AA)
        cv2.circle(image, centre, 4, _CAN, -1, cv2.LINE_AA)
    elif mark == "obstacle":
        cv2.circle(image, centre, 6, _BALL, -1, cv2.LINE_AA)
        cv2.circle(image, centre, 6, _TEXT, 1, cv2.LINE_AA)
    elif mark == "labbot":
        cv2.circle(image, centre, 6, _LABBOT, -1, cv2.LINE_AA)
    elif mark == "collision":
        for dx, dy in ((6, 6), (6, -6)):
            cv2.line(image, (cx - dx, cy - dy), (cx + dx, cy + dy), _CROSS, 2, cv2.LINE_AA)


def draw_topdown(scene: TopDownScene, poses: list[Pose], outcome: Outcome | None) -> bytes:
    """PNG bytes of ``scene`` with ``poses`` (the robot's path), ``outcome`` and the key below."""
    import cv2

    wall = scene.wall_mm
    scale = (SIZE_PX - 2 * MARGIN_PX) / (scene.room_mm + 2 * wall)
    image = np.full((SIZE_PX + key_height(scene), SIZE_PX, 3), 255, dtype=np.uint8)

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
            cv2.circle(image, tuple(int(v) for v in points[-1]), radius(scene.movers_radius_mm), _LABBOT, -1,
                       cv2.LINE_AA)
    cv2.circle(image, px(*scene.can_xy), radius(scene.reach_mm), _CAN, 1, cv2.LINE_AA)
    cv2.circle(image, px(*scene.can_xy), max(4, radius(scene.can_radius_mm)), _CAN, -1, cv2.LINE_AA)
    _draw_path(cv2, image, poses, px, radius(scene.robot_radius_mm))
    if scene.collision_xy is not None:
        cx, cy = px(*scene.collision_xy)
        for dx, dy in ((8, 8), (8, -8)):
            cv2.line(image, (cx - dx, cy - dy), (cx + dx, cy + dy), _CROSS, 3, cv2.LINE_AA)
    label = outcome.value if outcome is not None else "running"
    title = f"{scene.title}  {len(poses)} poses  outcome: {label}"
    font = 0.55
    while font > 0.35 and cv2.getTextSize(title, cv2.FONT_HERSHEY_SIMPLEX, font, 1)[0][0] > SIZE_PX - MARGIN_PX - 6:
        font -= 0.05  # a long seed: smaller, never cut off
    cv2.putText(image, title, (MARGIN_PX, 24), cv2.FONT_HERSHEY_SIMPLEX, font, _OUTCOME_COLOUR.get(outcome, _TEXT), 1,
                cv2.LINE_AA)
    bar_left = (MARGIN_PX, SIZE_PX - 14)
    bar_right = (MARGIN_PX + int(round(1000 * scale)), SIZE_PX - 14)
    cv2.line(image, bar_left, bar_right, _TEXT, 2)
    cv2.putText(image, "1 m", (bar_right[0] + 6, SIZE_PX - 10), cv2.FONT_HERSHEY_SIMPLEX, 0.45, _TEXT, 1, cv2.LINE_AA)
    _draw_key(cv2, image, scene)
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
