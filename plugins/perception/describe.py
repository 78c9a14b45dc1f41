"""What a camera image and a LiDAR scan show, as numbers and as short text -- and back.

The same analysis serves the ``text`` perception and any backend that must read the images
itself (the mock pilot): it looks only at the pixels and the ranges, never at ground truth.

The text lines have a fixed wording so a reader can turn them back into numbers
(:func:`parse_target_text`, :func:`parse_lidar_text`)::

    Camera: red can visible 12 deg left of centre, apparent height 18% of the image.
    Camera: the red can is not visible.
    LiDAR nearest obstacle: front 1.20 m, front-left clear, left 0.45 m, ... front-right no reading.

Bearings are positive to the left (counter-clockwise), like every angle in SafeEmbodAI. A
sector is 45 degrees wide and centred on its direction; "clear" means no return within the
LiDAR's range, "no reading" means the sector holds a missing beam.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass

import numpy as np

from safeembodai_core.models import LidarScan
from safeembodai_core.geometry.frames import wrap_deg

SECTORS = ("front", "front-left", "left", "back-left", "back", "back-right", "right", "front-right")
SECTOR_HALF_WIDTH_DEG = 22.5
_AHEAD_DEG = 0.5


@dataclass(frozen=True)
class TargetSighting:
    """The red target as seen in a camera image (None fields when not seen)."""

    seen: bool
    bearing_deg: float | None = None  # positive = left of centre
    height_fraction: float | None = None  # apparent height / image height
    pixels: int = 0


def find_red_target(image: np.ndarray, fov_deg: float = 60.0, min_pixels: int = 12) -> TargetSighting:
    """Locate the red can in an RGB image by colour."""
    r, g, b = image[..., 0], image[..., 1], image[..., 2]
    if image.dtype == np.uint8:  # r - max(g, b) > 70 where r > 120 (so r - 70 cannot wrap), in uint8
        mask = (r > 120) & (np.maximum(g, b) < r - np.uint8(70))
    else:
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
        beams = scan.ranges_mm[scan.sector(index * 45.0, SECTOR_HALF_WIDTH_DEG)]
        if np.isnan(beams).any():
            result[name] = math.nan
        else:
            result[name] = float(beams.min()) if beams.size else math.inf
    return result


def sector_clearance_from_points(points: np.ndarray) -> dict[str, float]:
    """Nearest point (mm) in each sector, for returns given as (M, 2) robot-frame points."""
    result = {name: math.inf for name in SECTORS}
    if points.size == 0:
        return result
    angles = np.degrees(np.arctan2(points[:, 1], points[:, 0]))
    distances = np.hypot(points[:, 0], points[:, 1])
    for index, name in enumerate(SECTORS):
        offset = wrap_deg(angles - index * 45.0)
        inside = np.abs(offset) <= SECTOR_HALF_WIDTH_DEG
        if inside.any():
            result[name] = float(distances[inside].min())
    return result


def describe_target(sighting: TargetSighting) -> str:
    if not sighting.seen:
        return "Camera: the red can is not visible."
    bearing, height = sighting.bearing_deg, sighting.height_fraction
    assert bearing is not None and height is not None  # a sighting that is seen has both
    size = f"apparent height {100 * height:.0f}% of the image"
    if abs(bearing) < _AHEAD_DEG:
        return f"Camera: red can visible straight ahead, {size}."
    side = "left" if bearing > 0 else "right"
    return f"Camera: red can visible {abs(bearing):.0f} deg {side} of centre, {size}."


def describe_lidar(clearance: dict[str, float]) -> str:
    def fmt(value: float) -> str:
        if math.isnan(value):
            return "no reading"
        return "clear" if math.isinf(value) else f"{value / 1000:.2f} m"

    return "LiDAR nearest obstacle: " + ", ".join(f"{name} {fmt(v)}" for name, v in clearance.items()) + "."


_TARGET = re.compile(
    r"red can visible (?:(?P<ahead>straight ahead)|(?P<deg>\d+(?:\.\d+)?) deg (?P<side>left|right) of centre)"
    r", apparent height (?P<height>\d+(?:\.\d+)?)% of the image"
)
_NOT_SEEN = re.compile(r"red can is not visible")
_SECTOR = re.compile(r"\b(front-left|front-right|back-left|back-right|front|back|left|right) "
                     r"(clear|no reading|(\d+(?:\.\d+)?) m)\b")


def parse_target_text(text: str) -> TargetSighting | None:
    """The sighting a camera line describes; None when ``text`` holds no camera line."""
    match = _TARGET.search(text)
    if match is None:
        return TargetSighting(seen=False) if _NOT_SEEN.search(text) else None
    bearing = 0.0 if match["ahead"] else float(match["deg"]) * (1 if match["side"] == "left" else -1)
    return TargetSighting(seen=True, bearing_deg=bearing, height_fraction=float(match["height"]) / 100)


def parse_lidar_text(text: str) -> dict[str, float] | None:
    """Sector clearances (mm) from a LiDAR line; None when ``text`` holds none."""
    start = text.find("LiDAR nearest obstacle:")
    if start < 0:
        return None
    found: dict[str, float] = {}
    for name, value, metres in _SECTOR.findall(text[start:].split("\n", 1)[0]):
        found[name] = math.inf if value == "clear" else (math.nan if value == "no reading" else float(metres) * 1000)
    return found if set(found) == set(SECTORS) else None
