"""PNG bytes and back: the same bytes as before, and a remembered picture decodes to its pixels."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from safeembodai_plugins.perception import pngs
from safeembodai_plugins.perception.describe import find_red_target
from safeembodai_plugins.perception.lidar_image import _RING, _DARK, _scale_px_per_mm, read_lidar_image
from safeembodai_plugins.perception.render import draw_lidar_image, encode_png
from safeembodai_core.models import LidarScan


def picture(seed: int, shape=(240, 320, 3)) -> np.ndarray:
    rng = np.random.default_rng(seed)
    image = rng.integers(0, 256, shape, dtype=np.uint8)
    image[40:90, 100:140] = (200, 20, 30)  # a red patch, for the red-target reading
    return image


def cv2_decode(data: bytes) -> np.ndarray:
    return np.ascontiguousarray(cv2.imdecode(np.frombuffer(data, np.uint8), cv2.IMREAD_COLOR)[..., ::-1])


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_encoding_gives_the_bytes_a_reversed_slice_gave(seed):
    image = picture(seed)
    ok, before = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
    assert ok and encode_png(image) == before.tobytes()


def test_a_remembered_picture_decodes_to_its_pixels_in_a_copy_of_its_own():
    image = picture(3)
    data = encode_png(image)
    first = pngs.decode_png(data)
    assert np.array_equal(first, image) and np.array_equal(first, cv2_decode(data))
    first[:] = 0  # the reader's copy: what is remembered is untouched
    assert np.array_equal(pngs.decode_png(data), image)
    image[:] = 7  # nor does the caller's array, changed after encoding, change what it decodes to
    assert np.array_equal(pngs.decode_png(data), cv2_decode(data))


def test_a_picture_not_drawn_here_is_decoded(monkeypatch):
    image = picture(4)
    ok, data = cv2.imencode(".png", np.ascontiguousarray(image[..., ::-1]))
    assert np.array_equal(pngs.decode_png(data.tobytes()), image)
    with pytest.raises(ValueError):
        pngs.decode_png(b"not a picture")


def test_only_the_latest_pictures_are_remembered():
    datas = [encode_png(picture(10 + k, (24, 32, 3))) for k in range(pngs.REMEMBERED + 4)]
    assert len(pngs._drawn) == pngs.REMEMBERED
    assert datas[0] not in pngs._drawn and datas[-1] in pngs._drawn
    assert all(np.array_equal(pngs.decode_png(d), picture(10 + k, (24, 32, 3))) for k, d in enumerate(datas))


def test_an_image_that_is_not_rgb_bytes_is_encoded_as_before():
    grey = np.random.default_rng(5).integers(0, 256, (20, 30), dtype=np.uint8)
    ok, before = cv2.imencode(".png", np.ascontiguousarray(grey[..., ::-1]))
    assert ok and encode_png(grey) == before.tobytes()


@pytest.mark.parametrize("seed", range(6))
def test_the_red_target_mask_in_uint8_finds_what_int16_found(seed):
    image = picture(seed)
    image[..., 0] = np.where(np.random.default_rng(seed).random(image.shape[:2]) < 0.3, 255, image[..., 0])
    wide = image.astype(np.int16)
    assert find_red_target(image) == find_red_target(wide)  # the uint8 path and the int16 one


def reductions_reading(image: np.ndarray, fallback_range_mm: float) -> tuple[float, np.ndarray]:
    """The scale and the dark pixels as read with ``np.all(axis=-1)`` and ``max(axis=-1)``."""
    centre = image.shape[0] / 2.0
    rows, cols = np.nonzero(np.all(image == _RING, axis=-1))
    scale = centre / fallback_range_mm
    if rows.size:
        radii = np.hypot(rows - int(centre), cols - int(centre))
        radius = float(np.median(radii[radii <= radii.min() + 1.5]))
        scale = radius / 1000.0 if radius > 2 else scale
    return scale, np.column_stack(np.nonzero(image.max(axis=-1) < _DARK))


@pytest.mark.parametrize("size, range_mm", [(240, 4000.0), (200, 900.0), (320, 6000.0)])
def test_the_lidar_picture_is_read_as_the_all_and_max_reductions_read_it(size, range_mm):
    angles = np.radians(np.arange(360))
    ranges = 800 + 2500 * np.abs(np.sin(3 * angles))
    image = draw_lidar_image(LidarScan(ranges_mm=ranges, max_range_mm=6000.0), size, range_mm)
    scale, dark = reductions_reading(image, range_mm)
    assert _scale_px_per_mm(image, range_mm) == scale
    reading = read_lidar_image(encode_png(image), range_mm)
    centre = size / 2.0
    assert np.array_equal(reading.points_mm, np.column_stack(((centre - dark[:, 0]) / scale,
                                                              (centre - dark[:, 1]) / scale)))
