"""The robot's body as environments describe it and validators reason about it.

Its own module so that :mod:`safeembodai_core.components` (the interfaces) and
:mod:`safeembodai_core.validation` (the rules' context) can both use it without importing each
other; ``safeembodai_core.components.RobotSpec`` is the same class.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class RobotSpec:
    """The robot's body as validators need it (millimetres)."""

    radius_mm: float = 170.0
    width_mm: float = 340.0
    length_mm: float = 340.0
