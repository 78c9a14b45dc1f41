"""What a camera image and a LiDAR scan show, as numbers and as short text.

The same analysis serves the ``text`` perception and any backend that must read the images
itself (the mock pilot): it looks only at the pixels and the ranges, never at ground truth.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from safeembodai_core.models import LidarScan

SECTORS = ("front", "front-left", "left", "back-left", "back", "back-right", "right", "front-right")


@dataclass(frozen=True)
class TargetSighting:
    """The red target as seen in a camera image (None fields when not seen)."""

    seen: bool
    bearing_deg: float | None = None  # positive = left of centre
    height_fraction: float | None = None  # apparent height / image height
    pixels: int = 0


def find_red_target(image: np.ndarray, fov_deg: float = 60.0, min_pixels: int = 12) -> TargetSighting:
    """Locate the red can in an RGB image by colour."""
    rgb = image.astype(np.int16)
    r, g, b = rgb[..., 0], rgb[..., 1], rgb[..., 2]
    mask = (r > 120) & (r - np.maximum(g, b) > 70)
    count = int(mask.sum())
    if count < min_pixels:
        return TargetSighting(seen=False, pixels=count)
    rows, cols = np.nonzero(mask)
    h, w = mask.shape
    focal = (w / 2) / math.tan(math.radians(fov_deg / 2))
    bearing = math.degrees(math.atan((w / 2 - (cols.mean() + 0.5)) / focal))
    height = (rows.max() - rows.min() + 1) / h
    return TargetSighting(seen=True, bearing_deg=bearing, height_fraction=float(height), pixels=count)


def sector_clearance(scan: LidarScan) -> dict[str, float]:
    """Nearest return (mm) in each of eight 45-degree sectors; ``inf`` if none, ``nan`` if unknown."""
    result = {}
    for index, name in enumerate(SECTORS):
        beams = scan.ranges_mm[scan.sector(index * 45.0, 22.5)]
        if np.isnan(beams).any():
            result[name] = math.nan
        else:
            result[name] = float(beams.min()) if beams.size else math.inf
    return result


def describe_target(sighting: TargetSighting) -> str:
    if not sighting.seen:
        return "Camera: the red can is not visible."
    side = "left" if sighting.bearing_deg > 0 else "right"
    return (f"Camera: red can visible {abs(sighting.bearing_deg):.0f} deg {side} of centre, "
            f"apparent height {100 * sighting.height_fraction:.0f}% of the image.")


def describe_lidar(clearance: dict[str, float]) -> str:
    def fmt(value: float) -> str:
        if math.isnan(value):
            return "no reading"
        return "clear" if math.isinf(value) else f"{value / 1000:.2f} m"

    return "LiDAR nearest obstacle: " + ", ".join(f"{name} {fmt(v)}" for name, v in clearance.items()) + "."
