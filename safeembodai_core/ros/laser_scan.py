"""``sensor_msgs/LaserScan`` into the rules' scan format (issue 23).

A ROS scan is read with REP 117's semantics: ``ranges`` in metres, beam ``i`` at ``angle_min + i *
angle_increment`` radians in the sensor's frame (counter-clockwise, x forward); a finite value in
[``range_min``, ``range_max``] is a return; ``+inf`` or a value beyond ``range_max`` is no return
(free out to ``range_max``); ``-inf`` is a detection too close to measure (taken as an obstacle at
the sensor: the most cautious reading); ``nan`` or a value below ``range_min`` is no reading.

:meth:`LaserScan.to_lidar_scan` moves every beam's end into the robot's frame through the sensor's
mounting (:class:`SensorMount`) and bins it by its bearing from the robot's centre into ``N`` beams
evenly round the robot, ``N`` = 360 / the sensor's increment for a sensor at the centre (bins and
beams coincide), half that for an offset one (the parallax of the offset must not leave a bin
empty). A bin holds the nearest return of its beams, ``inf`` when its beams saw only free space,
and ``nan`` when no beam of the sensor pointed into it -- **outside the field of view a direction
is unknown, never free** -- or when its beams gave no reading. ``max_range_mm`` is the sensor's
range less the mounting offset: the least distance from the centre out to which a free beam saw.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence, cast

import numpy as np

from ..models import LidarScan

#: Most beams a converted scan gets (0.05 degree): beyond this a finer sensor is binned coarser.
MAX_BEAMS = 7200
#: The finest increment read (radians): finer is no scanner's, and would overflow the beam count.
MIN_INCREMENT = 1e-6
#: The farthest range read (metres): no scanner's reaches it, and millimetres stay finite.
MAX_RANGE_M = 100_000.0


def finite_number(owner: str, name: str, value: Any, unit: str = "") -> float:
    """``value`` as a finite float, or a ``ValueError`` naming ``owner.name`` (``name`` alone when
    ``owner`` is empty) and, when given, the ``unit`` it is read in."""
    label, of = f"{owner}.{name}" if owner else name, f" of {unit}" if unit else ""
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{label} must be a number{of}, got {value!r}") from None
    if not math.isfinite(number):
        raise ValueError(f"{label} must be {'a finite number' + of if unit else 'finite'}, got {value!r}")
    return number


@dataclass(frozen=True)
class SensorMount:
    """Where the scanner sits on the robot: its origin in the robot frame (mm, x forward, y left)
    and its yaw (degrees counter-clockwise from the robot's heading)."""

    x_mm: float = 0.0
    y_mm: float = 0.0
    yaw_deg: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x_mm", "y_mm", "yaw_deg"):
            object.__setattr__(self, name, finite_number("SensorMount", name, getattr(self, name)))

    @property
    def offset_mm(self) -> float:
        return math.hypot(self.x_mm, self.y_mm)


@dataclass(frozen=True)
class LaserScan:
    """The fields of ``sensor_msgs/LaserScan`` the guard reads (SI units, as ROS sends them), and
    the sensor's mounting. ``angle_max`` is kept for the record; beam angles follow ``angle_min``
    and ``angle_increment``, as ROS defines them."""

    angle_min: float
    angle_increment: float
    ranges: Sequence[float]
    range_min: float
    range_max: float
    angle_max: float | None = None
    mount: SensorMount = field(default_factory=SensorMount)

    def __post_init__(self) -> None:
        for name in ("angle_min", "angle_increment", "range_min", "range_max"):
            object.__setattr__(self, name, finite_number("LaserScan", name, getattr(self, name)))
        if self.angle_max is not None:
            object.__setattr__(self, "angle_max", finite_number("LaserScan", "angle_max", self.angle_max))
        if not MIN_INCREMENT <= abs(self.angle_increment) <= 2 * math.pi:
            raise ValueError(f"LaserScan.angle_increment must be between {MIN_INCREMENT:g} and 2 pi radians (either "
                             f"sign), got {self.angle_increment!r}")
        if self.range_max > MAX_RANGE_M:
            raise ValueError(f"LaserScan.range_max must be at most {MAX_RANGE_M:g} m, got {self.range_max!r}")
        if not 0.0 <= self.range_min < self.range_max:
            raise ValueError(f"LaserScan needs 0 <= range_min < range_max, got range_min {self.range_min!r}, "
                             f"range_max {self.range_max!r}")
        try:
            ranges = np.array(self.ranges, dtype=float, copy=True)
        except (TypeError, ValueError):
            raise ValueError("LaserScan.ranges must be a sequence of numbers (metres)") from None
        if ranges.ndim != 1 or ranges.size == 0:
            raise ValueError(f"LaserScan.ranges must hold at least one beam, got shape {ranges.shape}")
        ranges.flags.writeable = False
        object.__setattr__(self, "ranges", ranges)
        if not isinstance(self.mount, SensorMount):
            raise ValueError(f"LaserScan.mount must be a SensorMount, got {type(self.mount).__name__}")

    @classmethod
    def from_ros(cls, message: Any, mount: SensorMount | None = None) -> LaserScan:
        """A decoded ``sensor_msgs/msg/LaserScan`` (``rosbags``, ``mcap_ros2``, ``rclpy``: anything
        with its fields as attributes) with the sensor's ``mount`` on the robot (default: at the
        centre, facing forward; ROS keeps it in TF, which a message does not carry)."""
        missing = [name for name in ("angle_min", "angle_increment", "range_min", "range_max", "ranges")
                   if not hasattr(message, name)]
        if missing:
            raise ValueError(f"not a sensor_msgs/LaserScan: no {', '.join(missing)} on {type(message).__name__}")
        return cls(angle_min=message.angle_min, angle_increment=message.angle_increment, ranges=message.ranges,
                   range_min=message.range_min, range_max=message.range_max,
                   angle_max=getattr(message, "angle_max", None), mount=mount or SensorMount())

    def beams(self) -> int:
        """How many beams round the robot the converted scan has."""
        step_deg = abs(math.degrees(self.angle_increment))
        per_turn = 360.0 / step_deg if self.mount.offset_mm == 0.0 else 180.0 / step_deg
        return int(min(MAX_BEAMS, max(4, math.floor(per_turn + 1e-6))))

    def to_lidar_scan(self) -> LidarScan:
        """The scan as the rules read it (module docstring)."""
        ranges = cast("np.ndarray", self.ranges)  # __post_init__ made it an array
        with np.errstate(invalid="ignore"):
            returned = np.isfinite(ranges) & (ranges >= self.range_min) & (ranges <= self.range_max)
            free = np.isposinf(ranges) | (np.isfinite(ranges) & (ranges > self.range_max))
        close = np.isneginf(ranges)
        seen = returned | free | close
        reach_m = np.where(returned, ranges, np.where(close, 0.0, self.range_max))
        angles = self.angle_min + np.arange(ranges.size) * self.angle_increment + math.radians(self.mount.yaw_deg)
        x = self.mount.x_mm + reach_m * 1000.0 * np.cos(angles)
        y = self.mount.y_mm + reach_m * 1000.0 * np.sin(angles)
        # a too-close detection sits at the sensor, but keeps its beam's direction for its bin
        ahead_m = np.where(close, max(self.range_min, 1e-3), reach_m)
        count = self.beams()
        width = 2.0 * math.pi / count
        bearing = np.arctan2(self.mount.y_mm + ahead_m * 1000.0 * np.sin(angles),
                             self.mount.x_mm + ahead_m * 1000.0 * np.cos(angles))
        bins = np.rint(bearing / width).astype(int) % count
        # a centred scanner's distances are its ranges (no trigonometric round trip: the same numbers)
        distance = reach_m * 1000.0 if self.mount.offset_mm == 0.0 else np.hypot(x, y)
        nearest = np.full(count, np.inf)
        obstacle = returned | close
        np.minimum.at(nearest, bins[obstacle], distance[obstacle])
        looked = np.zeros(count, dtype=bool)
        looked[bins[seen]] = True
        out = np.where(looked, nearest, np.nan)  # a bin no beam saw into is unknown, never free
        max_range_mm = max(self.range_max * 1000.0 - self.mount.offset_mm, 1.0)
        exact = np.column_stack((x[obstacle], y[obstacle]))  # where the returns are, before binning
        return LidarScan(out, max_range_mm, returns_mm=exact)
