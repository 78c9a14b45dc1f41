"""The two perception components: images (PNG) and text."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from safeembodai_core.contracts.components import Perception
from safeembodai_core.models import ImagePart, LidarScan, Modalities, Observation

from .describe import describe_lidar, describe_target, find_red_target, sector_clearance
from .pngs import encode_png

__all__ = ["ImagePerception", "TextPerception", "draw_lidar_image", "encode_png"]


@lru_cache(maxsize=1)
def _dot_offsets() -> tuple[np.ndarray, np.ndarray]:
    """Pixel offsets of a filled radius-2 dot exactly as ``cv2.circle`` draws it."""
    import cv2

    stamp = np.zeros((5, 5), dtype=np.uint8)
    cv2.circle(stamp, (2, 2), 2, 1, -1)
    rows, cols = np.nonzero(stamp)
    return rows - 2, cols - 2


def draw_lidar_image(scan: LidarScan, size_px: int, range_mm: float) -> np.ndarray:
    """Top-down map: robot at the centre facing up, returns as dark dots, range rings every metre."""
    import cv2

    image = np.full((size_px, size_px, 3), 255, dtype=np.uint8)
    centre = size_px / 2.0
    scale = centre / range_mm
    for ring in range(1, int(range_mm // 1000) + 1):
        cv2.circle(image, (int(centre), int(centre)), int(ring * 1000 * scale), (215, 215, 215), 1)
    points = scan.points()
    if points.size:
        # robot frame x forward (up), y left (image left)
        cols = np.rint(centre - points[:, 1] * scale).astype(int)
        rows = np.rint(centre - points[:, 0] * scale).astype(int)
        inside = (cols >= 0) & (cols < size_px) & (rows >= 0) & (rows < size_px)
        dr, dc = _dot_offsets()
        dot_rows = (rows[inside][:, None] + dr[None, :]).ravel()
        dot_cols = (cols[inside][:, None] + dc[None, :]).ravel()
        keep = (dot_rows >= 0) & (dot_rows < size_px) & (dot_cols >= 0) & (dot_cols < size_px)
        image[dot_rows[keep], dot_cols[keep]] = 0  # one vectorised stamp instead of a circle per return
    tip = (int(centre), int(centre - 18))
    cv2.circle(image, (int(centre), int(centre)), 6, (0, 120, 255), -1)
    cv2.line(image, (int(centre), int(centre)), tip, (0, 120, 255), 2)
    return image


def _texts(observation: Observation, fov: float, min_pixels: int = 12) -> dict[str, str]:
    texts = {}
    if observation.camera is not None:
        texts["camera_text"] = describe_target(find_red_target(observation.camera, fov, min_pixels))
    if observation.lidar is not None:
        texts["lidar_text"] = describe_lidar(sector_clearance(observation.lidar))
    return texts


class ImagePerception(Perception):
    def __init__(self, options) -> None:
        self.options = options

    def perceive(self, observation: Observation) -> Modalities:
        o = self.options
        images = {}
        if observation.camera is not None:
            h, w = observation.camera.shape[:2]
            images["camera_image"] = ImagePart("camera_image", encode_png(observation.camera), width=w, height=h)
        if observation.lidar is not None:
            picture = draw_lidar_image(observation.lidar, o.lidar_image_px, o.lidar_image_range_mm)
            images["lidar_image"] = ImagePart("lidar_image", encode_png(picture), width=o.lidar_image_px,
                                              height=o.lidar_image_px)
        texts = _texts(observation, o.camera_fov_deg) if o.with_text else {}
        return Modalities(images=images, texts=texts)


class TextPerception(Perception):
    def __init__(self, options) -> None:
        self.options = options

    def perceive(self, observation: Observation) -> Modalities:
        return Modalities(texts=_texts(observation, self.options.camera_fov_deg, self.options.min_target_pixels))
