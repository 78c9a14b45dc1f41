"""PNG bytes of an RGB image and back, with the pictures this process drew remembered.

The ``images`` perception encodes two pictures a step; a reader in the same process (the mock
pilot) decodes them again moments later. PNG is lossless, so the decoded pixels are the array
that was encoded: :func:`decode_png` answers bytes that :func:`encode_png` made recently with a
copy of that array instead of decoding (the last :data:`REMEMBERED` pictures; anything else is
decoded). The channel swaps (OpenCV works in BGR) go through ``cv2.cvtColor``: the same bytes as a
reversed numpy slice, without the slow strided copy.
"""

from __future__ import annotations

import threading
from collections import OrderedDict

import numpy as np

#: Pictures remembered (bytes -> pixels): a step's two, with room for a few trials in threads.
REMEMBERED = 16
_drawn: OrderedDict[bytes, np.ndarray] = OrderedDict()
_lock = threading.Lock()


def encode_png(rgb: np.ndarray) -> bytes:
    """PNG bytes of an RGB uint8 image."""
    import cv2

    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:  # not a picture we remember: as it was
        ok, data = cv2.imencode(".png", np.ascontiguousarray(rgb[..., ::-1]))
        if not ok:
            raise ValueError("could not encode image as PNG")
        return data.tobytes()
    pixels = np.ascontiguousarray(rgb)
    ok, data = cv2.imencode(".png", cv2.cvtColor(pixels, cv2.COLOR_RGB2BGR))
    if not ok:
        raise ValueError("could not encode image as PNG")
    encoded = data.tobytes()
    kept = pixels.copy()
    kept.flags.writeable = False
    with _lock:
        _drawn[encoded] = kept
        _drawn.move_to_end(encoded)
        while len(_drawn) > REMEMBERED:
            _drawn.popitem(last=False)
    return encoded


def decode_png(data: bytes) -> np.ndarray:
    """An RGB uint8 array from PNG (or any format OpenCV reads) bytes."""
    with _lock:
        kept = _drawn.get(data) if isinstance(data, bytes) else None
    if kept is not None:
        return kept.copy()
    import cv2

    image = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
    if image is None:
        raise ValueError("image bytes could not be decoded")
    return cv2.cvtColor(image, cv2.COLOR_BGR2RGB)
