"""Reading images back: the camera PNG and the top-down LiDAR picture as a reader sees them.

A vision model reads the LiDAR image drawn by :func:`~.render.draw_lidar_image` -- robot at the
centre facing up, returns as dark dots, light grey range rings every metre -- and so does the
mock pilot, through :func:`read_lidar_image`. The scale comes from the rings (the first is at
one metre), so nothing but the picture is needed; a picture whose range is under a metre has
no ring and uses ``fallback_range_mm``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from safeembodai_core.geometry.frames import wrap_deg

from .pngs import decode_png

__all__ = ["LidarPicture", "decode_png", "nearest_in_cone", "read_lidar_image"]

_RING = 215
_DARK = 90


@dataclass(frozen=True)
class LidarPicture:
    """Returns read from a LiDAR image, as (M, 2) robot-frame points in millimetres."""

    points_mm: np.ndarray
    range_mm: float

    def nearest_in_cone(self, centre_deg: float, half_width_deg: float) -> float:
        """Distance (mm) of the nearest return within ``half_width_deg`` of ``centre_deg``; inf if none."""
        return nearest_in_cone(self.points_mm, centre_deg, half_width_deg)


def nearest_in_cone(points: np.ndarray, centre_deg: float, half_width_deg: float) -> float:
    if points.size == 0:
        return math.inf
    angles = np.degrees(np.arctan2(points[:, 1], points[:, 0]))
    offset = wrap_deg(angles - centre_deg)
    inside = np.abs(offset) <= half_width_deg
    if not inside.any():
        return math.inf
    return float(np.hypot(points[inside, 0], points[inside, 1]).min())


def _scale_px_per_mm(image: np.ndarray, fallback_range_mm: float) -> float:
    size = image.shape[0]
    centre = size / 2.0
    ring = (image[..., 0] == _RING) & (image[..., 1] == _RING) & (image[..., 2] == _RING)  # np.all(axis=-1), faster
    rows, cols = np.nonzero(ring)
    if rows.size:
        radii = np.hypot(rows - int(centre), cols - int(centre))
        first = radii[radii <= radii.min() + 1.5]
        radius = float(np.median(first))
        if radius > 2:
            return radius / 1000.0
    return centre / fallback_range_mm


def read_lidar_image(data: bytes, fallback_range_mm: float = 4000.0) -> LidarPicture:
    """The returns a LiDAR picture shows, in the robot frame (x forward, y left, mm)."""
    image = decode_png(data)
    if image.ndim != 3 or image.shape[0] != image.shape[1]:
        raise ValueError(f"a LiDAR image must be square, got {image.shape[:2]}")
    scale = _scale_px_per_mm(image, fallback_range_mm)
    centre = image.shape[0] / 2.0
    dark = np.maximum(np.maximum(image[..., 0], image[..., 1]), image[..., 2]) < _DARK  # max(axis=-1), faster
    rows, cols = np.nonzero(dark)
    points = np.column_stack(((centre - rows) / scale, (centre - cols) / scale)).astype(float)
    return LidarPicture(points_mm=points, range_mm=centre / scale)
