"""The robot's body as environments describe it and validators reason about it.

Its own module so that :mod:`safeembodai_core.contracts.components` (the interfaces) and
:mod:`safeembodai_core.validation.context` (the rules' context) can both use it without importing each
other; ``safeembodai_core.contracts.components.RobotSpec`` is the same class.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..geometry import Body, read_polygon


@dataclass(frozen=True)
class RobotSpec:
    """The robot's body as validators need it (millimetres).

    ``radius_mm``, ``width_mm`` and ``length_mm`` describe a round body (the paper's robots and the
    default). ``footprint_mm``, when given, is the body's outline as a simple polygon in the robot
    frame -- ``[(x, y), ...]``, x forward, y left, origin at the point the robot turns about -- and
    rules that judge the swept body (``swept_body``) use it instead of the disc. ``holonomic`` says
    the base can also drive sideways (``linear.y``); a sideways command to a robot without it is an
    error, never a guess.
    """

    radius_mm: float = 170.0
    width_mm: float = 340.0
    length_mm: float = 340.0
    footprint_mm: tuple[tuple[float, float], ...] | None = None
    holonomic: bool = False

    def __post_init__(self) -> None:
        if self.footprint_mm is not None:
            polygon = read_polygon(self.footprint_mm, "RobotSpec.footprint_mm")
            object.__setattr__(self, "footprint_mm", tuple((float(x), float(y)) for x, y in polygon))

    def body(self, margin_mm: float = 0.0) -> Body:
        """The body rules sweep: the footprint when given, else the disc of ``radius_mm``; grown by ``margin_mm``."""
        return Body.of(self.radius_mm, self.footprint_mm, margin_mm)
