"""The angle wrap is written once (``safeembodai_core.geometry.wrap_deg``): a new inline copy fails here."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from safeembodai_core.geometry import wrap_deg

REPO = Path(__file__).resolve().parents[2]
INLINE = re.compile(r"\+ 180(\.0)?\) % 360(\.0)? - 180")


def test_no_module_wraps_an_angle_inline():
    found = [f"{path.relative_to(REPO)}:{number}" for folder in ("safeembodai_core", "plugins")
             for path in sorted((REPO / folder).rglob("*.py"))
             for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if INLINE.search(line) and "def wrap_deg" not in line and path.name != "frames.py"]
    assert not found, f"wrap angles with safeembodai_core.geometry.wrap_deg: {found}"


@pytest.mark.parametrize("angle, wrapped", [(180.0, -180.0), (-180.0, -180.0), (190.0, -170.0), (-540.0, -180.0),
                                            (359.5, -0.5), (0.0, 0.0)])
def test_wrap_deg_maps_to_the_half_open_range(angle, wrapped):
    assert wrap_deg(angle) == pytest.approx(wrapped)
    assert wrap_deg(np.array([angle]))[0] == pytest.approx(wrapped)
