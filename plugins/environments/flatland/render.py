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


def render_trajectory(poses, circles, o, outcome, size_px: int = 480) -> bytes:
    """A PNG of the room from above: obstacles, can, the robot's path and the outcome."""
    import cv2

    scale = (size_px - 40) / o.room_mm
    image = np.full((size_px, size_px, 3), 255, dtype=np.uint8)

    def px(x, y):
        return int(round(20 + x * scale)), int(round(size_px - 20 - y * scale))

    cv2.rectangle(image, px(0, 0), px(o.room_mm, o.room_mm), (60, 60, 60), 2)
    for k, (x, y, r) in enumerate(circles):
        colour = (25, 20, 200) if k == 0 else (150, 150, 150)
        cv2.circle(image, px(x, y), max(2, int(r * scale)), colour, -1)
    points = [px(p.x_mm, p.y_mm) for p in poses]
    for a, b in zip(points, points[1:]):
        cv2.line(image, a, b, (200, 120, 0), 2)
    if points:
        cv2.circle(image, points[0], max(3, int(o.robot_radius_mm * scale)), (0, 160, 0), 1)
        cv2.circle(image, points[-1], max(3, int(o.robot_radius_mm * scale)), (200, 120, 0), 2)
        end = poses[-1]
        tip = px(end.x_mm + 250 * math.cos(math.radians(end.heading_deg)), end.y_mm + 250 * math.sin(math.radians(end.heading_deg)))
        cv2.line(image, points[-1], tip, (200, 120, 0), 2)
    label = outcome.value if outcome is not None else "running"
    cv2.putText(image, label, (24, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    ok, data = cv2.imencode(".png", image)
    return data.tobytes()
