"""The caption the core adds above every trial's picture: which trial (arm, condition) it is and,
for a simulated backend, that no LLM drove the robot.

An environment draws its picture with ``trajectory_png(poses, outcome)`` (the plugin contract of
``docs/plugin_hooks.md``) and knows nothing of arms or backends; the runner puts this caption
around whatever it drew. A picture OpenCV cannot read (not a PNG or JPEG, say) is kept as drawn.
"""

from __future__ import annotations

import numpy as np

from ..logs import get_logger
from ..models import TrialSpec

log = get_logger(__name__)

_ROW_PX, _FONT, _MIN_FONT, _PAD_PX = 22, 0.5, 0.3, 8
_TEXT, _WARNING = (20, 20, 20), (30, 30, 170)  # BGR: the simulated note in dark red


def caption_lines(spec: TrialSpec, simulated: str | None) -> list[str]:
    """The caption of a trial's picture: its id with arm and condition, and a simulated backend's
    banner (``BackendDescription.simulated``)."""
    lines = [f"trial {spec.trial_id}: arm {spec.arm}, condition {spec.condition}"]
    if simulated:
        lines.append(simulated)
    return lines


def _as_bgr(image: np.ndarray) -> np.ndarray | None:
    """An 8-bit picture as BGR (transparency over white); None for a kind not handled."""
    import cv2

    if image.dtype != np.uint8:
        return None
    if image.ndim == 2:
        return cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
    if image.ndim == 3 and image.shape[2] == 3:
        return image
    if image.ndim == 3 and image.shape[2] == 4:
        alpha = image[:, :, 3:4].astype(np.float64) / 255.0
        return (image[:, :, :3] * alpha + 255.0 * (1.0 - alpha)).round().astype(np.uint8)
    return None


def captioned(picture: bytes, lines: list[str]) -> bytes:
    """``picture`` (PNG bytes) with ``lines`` written in a strip above it, as PNG bytes.

    The first line is plain, the others (a simulated backend's note) dark red; a line too long for
    the picture's width is written smaller. A picture that cannot be read is returned unchanged.
    """
    import cv2

    image = cv2.imdecode(np.frombuffer(picture, np.uint8), cv2.IMREAD_UNCHANGED) if picture else None
    image = _as_bgr(image) if image is not None else None
    if image is None:
        log.warning("trajectory.caption_skipped", reason="the picture is not an 8-bit image OpenCV can read")
        return picture
    width = image.shape[1]
    strip = np.full((_PAD_PX + _ROW_PX * len(lines), width, 3), 255, dtype=np.uint8)
    for k, line in enumerate(lines):
        font = _FONT
        while font > _MIN_FONT and cv2.getTextSize(line, cv2.FONT_HERSHEY_SIMPLEX, font, 1)[0][0] > width - 12:
            font -= 0.05
        cv2.putText(strip, line, (6, _PAD_PX // 2 + _ROW_PX * k + 16), cv2.FONT_HERSHEY_SIMPLEX, font,
                    _TEXT if k == 0 else _WARNING, 1, cv2.LINE_AA)
    ok, data = cv2.imencode(".png", np.vstack([strip, image]))
    return data.tobytes() if ok else picture
