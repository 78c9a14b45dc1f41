"""Pictures of the flatland world: the robot's camera view and a top-down trajectory."""

from __future__ import annotations

import math

import numpy as np

from .geometry import circle_hits

WALL_HEIGHT_MM = 500.0
CAMERA_HEIGHT_MM = 150.0
CAN_HEIGHT_MM = 120.0
_FLOOR = np.array([96, 96, 96], dtype=np.uint8)
_SKY = np.array([180, 190, 200], dtype=np.uint8)
_WALL = np.array([205, 200, 185], dtype=np.float64)
_CAN = np.array([200, 20, 25], dtype=np.float64)
_OBSTACLE = np.array([235, 235, 235], dtype=np.float64)


def _shade(colour: np.ndarray, distance: np.ndarray) -> np.ndarray:
    factor = np.clip(1.0 - distance / 12000.0, 0.45, 1.0)
    return (colour[None, :] * factor[:, None]).astype(np.uint8)


def _paint(image, columns, depth, height_mm, colours, focal):
    h = image.shape[0]
    cy = h / 2.0
    safe = np.maximum(depth, 1.0)
    top = np.clip(np.floor(cy - focal * (height_mm - CAMERA_HEIGHT_MM) / safe), 0, h).astype(int)
    bottom = np.clip(np.ceil(cy + focal * CAMERA_HEIGHT_MM / safe), 0, h).astype(int)
    rows = np.arange(h)[:, None]
    mask = (rows >= top[None, :]) & (rows < bottom[None, :]) & columns[None, :]
    image[mask] = np.broadcast_to(colours[None, :, :], (h,) + colours.shape)[mask]


def render_camera(position: np.ndarray, heading: float, circles: np.ndarray, o) -> np.ndarray:
    """An RGB uint8 image (height x width x 3) of what the front camera sees."""
    w, h = o.camera_width, o.camera_height
    half = math.radians(o.camera_fov_deg / 2)
    focal = (w / 2) / math.tan(half)
    offsets = np.arctan((w / 2 - (np.arange(w) + 0.5)) / focal)  # left of centre is positive
    angles = math.radians(heading) + offsets
    image = np.empty((h, w, 3), dtype=np.uint8)
    image[: h // 2] = _SKY
    image[h // 2:] = _FLOOR
    dx, dy = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(dx > 0, (o.room_mm - position[0]) / dx, np.where(dx < 0, -position[0] / dx, np.inf))
        ty = np.where(dy > 0, (o.room_mm - position[1]) / dy, np.where(dy < 0, -position[1] / dy, np.inf))
    wall = np.minimum(tx, ty)
    cos_off = np.cos(offsets)
    _paint(image, np.ones(w, dtype=bool), wall * cos_off, WALL_HEIGHT_MM, _shade(_WALL, wall), focal)
    if len(circles):
        hits = circle_hits(position, dx, dy, circles)
        order = np.argsort(-np.hypot(circles[:, 0] - position[0], circles[:, 1] - position[1]))
        for k in order:
            t = hits[:, k]
            seen = np.isfinite(t) & (t < wall)
            if not seen.any():
                continue
            is_can = k == 0
            height = CAN_HEIGHT_MM if is_can else 2 * circles[k, 2]
            colour = _CAN if is_can else _OBSTACLE
            _paint(image, seen, np.where(seen, t * cos_off, 1.0), height, _shade(colour, np.where(seen, t, 0.0)), focal)
    return image


def render_trajectory(poses, circles, o, outcome, seed: int | None = None, collided: bool = False) -> bytes:
    """A PNG of the room from above, in the style every built-in world shares."""
    from ..topdown import TopDownScene, draw_topdown

    last = poses[-1] if poses else None
    scene = TopDownScene(
        title=f"flatland  seed {seed}", room_mm=o.room_mm, can_xy=(circles[0][0], circles[0][1]),
        can_radius_mm=o.can_radius_mm, reach_mm=o.reach_mm, robot_radius_mm=o.robot_radius_mm,
        obstacles=[tuple(c) for c in circles[1:]],
        collision_xy=(last.x_mm, last.y_mm) if collided and last is not None else None,
    )
    return draw_topdown(scene, poses, outcome)
