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
From an offset sensor the result is a :class:`MountedScan`, which also keeps the sensor's own view:
its beams binned round the sensor itself, as they would be for a sensor at the centre. Rebinned
round the centre, a beam's free segment no longer lies along its bin (the parallax), so the bins
cannot say what the sensor saw: a rule that derives unseen space from free space (``swept_body``)
derives it from the view, from where the sensor stood.

:meth:`LaserScan.from_ros` reads a decoded message (attributes) or a plain dict as rosbridge v2 sends
it (JSON). JSON has no ``inf`` or ``nan``: rosbridge writes ``+inf``, ``-inf`` and ``nan`` alike as
``null``, so a ``null`` range is read as ``null_range`` says -- ``"unknown"`` (no reading, as
``nan``: the default, fail-closed) or ``"no_return"`` (free out to ``range_max``, as ``+inf``), never
as too close (``-inf``), which ``null`` cannot tell apart (docs/robot_file.md). Every field is read
strictly: a missing one, a bool, text, an object where a number belongs or an integer too large for a
float is a ``ValueError`` naming the field.
"""

from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from decimal import Decimal
from typing import Any, Literal, Sequence, cast

import numpy as np

from ..models import LidarScan

#: Most beams a converted scan gets (0.05 degree): beyond this a finer sensor is binned coarser.
MAX_BEAMS = 7200
#: The finest increment read (radians): finer is no scanner's, and would overflow the beam count.
MIN_INCREMENT = 1e-6
#: The farthest range read (metres): no scanner's reaches it, and millimetres stay finite.
MAX_RANGE_M = 100_000.0


#: How a ``null`` range (rosbridge's ``inf``, ``-inf`` or ``nan``) is read: no reading, or no return.
NullRange = Literal["unknown", "no_return"]
NULL_RANGES: tuple[NullRange, ...] = ("unknown", "no_return")
#: The fields of a ``sensor_msgs/LaserScan`` a message must have, and all it may have.
NEEDED_FIELDS = ("angle_min", "angle_increment", "range_min", "range_max", "ranges")
SCAN_FIELDS = (*NEEDED_FIELDS, "angle_max", "time_increment", "scan_time", "intensities", "header")
_TEXT = (str, bytes, bytearray)


def shown(value: Any) -> str:
    """``value`` for an error message, short: a long text, a deep or long container, a huge integer cut."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of {value.bit_length()} bits"
    try:
        return reprlib.repr(value)
    except ValueError:  # an integer past Python's digit limit, inside a container
        return f"a {type(value).__name__}"


def real_number(owner: str, name: str, value: Any, unit: str = "") -> float:
    """``value`` as a float, ``inf`` and ``nan`` included, or a ``ValueError`` naming ``owner.name``
    (``name`` alone when ``owner`` is empty). Only a real number is one (``int``, ``float``, numpy's,
    ``Fraction``, ``Decimal``): a bool, text (``"10"``, ``"1_0"``, ``b"1"``), a container or an integer
    too large for a float is not -- the guard's numbers come from the wire and from callers alike, and
    no form of them is guessed."""
    label, of = f"{owner}.{name}" if owner else name, f" of {unit}" if unit else ""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Real, Decimal)):
        raise ValueError(f"{label} must be a number{of}, got {shown(value)}")
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        raise ValueError(f"{label} must be a number{of}, got {shown(value)}") from None


def finite_number(owner: str, name: str, value: Any, unit: str = "") -> float:
    """``value`` as a finite float, or a ``ValueError`` naming ``owner.name`` (``name`` alone when
    ``owner`` is empty) and, when given, the ``unit`` it is read in (:func:`real_number`)."""
    number = real_number(owner, name, value, unit)
    if not math.isfinite(number):
        label, of = f"{owner}.{name}" if owner else name, f" of {unit}" if unit else ""
        raise ValueError(f"{label} must be {'a finite number' + of if unit else 'finite'}, got {shown(value)}")
    return number


def read_ranges(values: Any) -> np.ndarray:
    """``LaserScan.ranges`` as a new float array: each a number (``inf`` and ``nan`` are ROS's own), or
    a ``ValueError`` naming the first that is not."""
    if isinstance(values, np.ndarray):
        if values.dtype.kind not in "fiu":
            raise ValueError(f"LaserScan.ranges must be numbers (metres), got an array of {values.dtype}")
        return values.astype(float)
    if isinstance(values, (*_TEXT, Mapping)) or not isinstance(values, Iterable):
        raise ValueError(f"LaserScan.ranges must be a sequence of numbers (metres), got {shown(values)}")
    items = list(values)
    if all(type(value) is float or type(value) is int for value in items):  # plain numbers, read at numpy's speed
        try:
            return np.array(items, dtype=float)
        except OverflowError:  # an integer too large for a float: named below
            pass
    for index, value in enumerate(items):
        if value is None:
            raise ValueError(f"LaserScan.ranges[{index}] is null (rosbridge's inf, -inf or nan): read the message "
                             "with LaserScan.from_ros(message, null_range=...)")
    return np.array([real_number("LaserScan", f"ranges[{index}]", value, "metres")
                     for index, value in enumerate(items)], dtype=float)


def _has(message: Any, name: str) -> bool:
    return name in message if isinstance(message, Mapping) else hasattr(message, name)


def _field(message: Any, name: str) -> Any:
    return message.get(name) if isinstance(message, Mapping) else getattr(message, name, None)


def _check_fields(message: Any) -> None:
    """Refuse a message that is not a ``sensor_msgs/LaserScan``: a field it lacks; of a dict, a key
    it has not, or a field of the wrong kind (the scan then checks the values of those it reads)."""
    missing = [name for name in NEEDED_FIELDS if not _has(message, name)]
    if missing:
        raise ValueError(f"not a sensor_msgs/LaserScan: no {', '.join(missing)} on {type(message).__name__}")
    if not isinstance(message, Mapping):
        return
    unknown = sorted(str(name) for name in message if name not in SCAN_FIELDS)
    if unknown:
        raise ValueError(f"not a sensor_msgs/LaserScan: unknown field {', '.join(map(shown, unknown))}")
    for name in ("angle_min", "angle_increment", "range_min", "range_max", "angle_max"):
        if name in message:  # text is no number on the wire
            real_number("LaserScan", name, message[name])
    for name in ("time_increment", "scan_time"):
        if message.get(name) is not None:  # null is nan on the wire; neither is read
            real_number("LaserScan", name, message[name], "seconds")
    if "header" in message and not isinstance(message["header"], Mapping):
        raise ValueError(f"LaserScan.header must be an object, got {shown(message['header'])}")
    if "intensities" in message and not isinstance(message["intensities"], list):
        raise ValueError(f"LaserScan.intensities must be a list, got {shown(message['intensities'])}")


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
    the sensor's mounting. Beam angles follow ``angle_min`` and ``angle_increment``, as ROS defines
    them; ``angle_max``, when given, must be where the last beam points (``angle_min + (len(ranges) -
    1) * angle_increment``, or one increment on, within half an increment): a scan that contradicts
    itself is refused, not judged."""

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
        ranges = read_ranges(self.ranges)
        if ranges.ndim != 1 or ranges.size == 0:
            raise ValueError(f"LaserScan.ranges must hold at least one beam, got shape {ranges.shape}")
        if self.angle_max is not None:
            self._check_angle_max(ranges.size, self.angle_max)
        ranges.flags.writeable = False
        object.__setattr__(self, "ranges", ranges)
        if not isinstance(self.mount, SensorMount):
            raise ValueError(f"LaserScan.mount must be a SensorMount, got {type(self.mount).__name__}")

    def _check_angle_max(self, count: int, angle_max: float) -> None:
        """Refuse a scan whose ``angle_max`` is not where its last beam points, within half an increment:
        ``angle_min + (count - 1) * angle_increment`` (REP 117), or one increment on (the end of the last
        beam's sector: how Nav2's own collision-monitor tests and some drivers write a full turn; the
        beams' angles are the same either way)."""
        last, half = self.angle_min + (count - 1) * self.angle_increment, abs(self.angle_increment) / 2
        if not (abs(last - angle_max) <= half or abs(last + self.angle_increment - angle_max) <= half):
            raise ValueError(
                f"LaserScan contradicts itself: angle_min {self.angle_min!r} + ({count} ranges - 1) * angle_increment "
                f"{self.angle_increment!r} puts the last beam at {last!r} rad, but angle_max is {angle_max!r} "
                "(they must agree within half an increment)")

    @classmethod
    def from_ros(cls, message: Any, mount: SensorMount | None = None, *,
                 null_range: NullRange = "unknown") -> LaserScan:
        """A ``sensor_msgs/msg/LaserScan``: decoded (``rosbags``, ``mcap_ros2``, ``rclpy``: anything
        with its fields as attributes) or as rosbridge sends it (a dict of its JSON), with the sensor's
        ``mount`` on the robot (default: at the centre, facing forward; ROS keeps it in TF, which a
        message does not carry). A ``null`` range is read as ``null_range`` says (module docstring)."""
        if null_range not in NULL_RANGES:
            raise ValueError(f"null_range must be one of {', '.join(NULL_RANGES)}, got {shown(null_range)}")
        _check_fields(message)
        ranges = _field(message, "ranges")
        if isinstance(ranges, list):
            read_as = math.nan if null_range == "unknown" else math.inf
            ranges = [read_as if value is None else value for value in ranges]
        return cls(angle_min=_field(message, "angle_min"), angle_increment=_field(message, "angle_increment"),
                   ranges=ranges, range_min=_field(message, "range_min"), range_max=_field(message, "range_max"),
                   angle_max=_field(message, "angle_max"), mount=mount or SensorMount())

    def beams(self, centred: bool | None = None) -> int:
        """How many beams round the robot the converted scan has; with ``centred``, round a scanner at
        the centre (True: its :attr:`MountedScan.view`) or off it (False), whatever the mounting."""
        step_deg = abs(math.degrees(self.angle_increment))
        centred = self.mount.offset_mm == 0.0 if centred is None else centred
        per_turn = 360.0 / step_deg if centred else 180.0 / step_deg
        return int(min(MAX_BEAMS, max(4, math.floor(per_turn + 1e-6))))

    def to_lidar_scan(self) -> LidarScan:
        """The scan as the rules read it (module docstring): from a scanner off the centre, a
        :class:`MountedScan`, which keeps the scanner's own view as well."""
        ranges = cast("np.ndarray", self.ranges)  # __post_init__ made it an array
        with np.errstate(invalid="ignore"):
            returned = np.isfinite(ranges) & (ranges >= self.range_min) & (ranges <= self.range_max)
            free = np.isposinf(ranges) | (np.isfinite(ranges) & (ranges > self.range_max))
        close = np.isneginf(ranges)
        angles = self.angle_min + np.arange(ranges.size) * self.angle_increment + math.radians(self.mount.yaw_deg)
        beams = _Beams(returned | close, returned | free | close, close,
                       np.where(returned, ranges, np.where(close, 0.0, self.range_max)), np.cos(angles), np.sin(angles),
                       max(self.range_min, 1e-3))
        x_mm, y_mm = self.mount.x_mm, self.mount.y_mm
        out, x, y = beams.binned(x_mm, y_mm, self.beams())
        max_range_mm = max(self.range_max * 1000.0 - self.mount.offset_mm, 1.0)
        exact = np.column_stack((x[beams.obstacle], y[beams.obstacle]))  # where the returns are, before binning
        if self.mount.offset_mm == 0.0:
            return LidarScan(out, max_range_mm, returns_mm=exact)
        view = LidarScan(beams.binned(0.0, 0.0, self.beams(centred=True))[0], self.range_max * 1000.0)
        return MountedScan(out, max_range_mm, returns_mm=exact, view=view, origin_mm=(x_mm, y_mm))


@dataclass(frozen=True)
class _Beams:
    """A scan's beams, each as the scanner saw it: ``obstacle`` (a return, or too close to measure),
    ``seen`` (a reading: those, or no return), ``close``; ``reach_m`` (a return's range, 0 when too
    close, ``range_max`` when free: how far it saw free), ``cos`` and ``sin`` of its direction (robot
    frame), ``ahead_m`` (how far along its beam a too-close detection is binned)."""

    obstacle: np.ndarray
    seen: np.ndarray
    close: np.ndarray
    reach_m: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    ahead_m: float

    def binned(self, x_mm: float, y_mm: float, count: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The ``count`` bins round a frame's origin, of beams from a scanner at (``x_mm``, ``y_mm``)
        in it (the robot's centre: the mounting; the scanner itself: 0, 0), each binned by the bearing
        of its end from the origin (module docstring), and the beams' ends (x, y in mm)."""
        reach_m, cos, sin, close = self.reach_m, self.cos, self.sin, self.close
        x = x_mm + reach_m * 1000.0 * cos
        y = y_mm + reach_m * 1000.0 * sin
        # a too-close detection sits at the sensor, but keeps its beam's direction for its bin
        ahead_m = np.where(close, self.ahead_m, reach_m)
        width = 2.0 * math.pi / count
        bearing = np.arctan2(y_mm + ahead_m * 1000.0 * sin, x_mm + ahead_m * 1000.0 * cos)
        bins = np.rint(bearing / width).astype(int) % count
        # a centred scanner's distances are its ranges (no trigonometric round trip: the same numbers)
        distance = reach_m * 1000.0 if x_mm == 0.0 and y_mm == 0.0 else np.hypot(x, y)
        nearest = np.full(count, np.inf)
        np.minimum.at(nearest, bins[self.obstacle], distance[self.obstacle])
        looked = np.zeros(count, dtype=bool)
        looked[bins[self.seen]] = True
        return np.where(looked, nearest, np.nan), x, y  # a bin no beam saw into is unknown, never free


@dataclass
class MountedScan(LidarScan):
    """A converted scan from a scanner off the robot's centre: the bins round the centre that every
    rule reads, and ``view``, the same beams binned round the scanner itself (as a scanner at the
    centre would be: bins and beams coincide), whose centre is ``origin_mm`` (x, y) in the robot
    frame. Rebinned round the centre, a beam's free segment no longer lies along its bin: at a shadow
    edge the parallax leaves a bin no beam ends in (unknown at every range, though the scanner saw
    into it) or one whose ray from the centre crosses a shadow the scanner did not see into. What the
    scanner saw is what ``view`` says, from where it stood: a rule that derives unseen space
    (``swept_body``) derives it from ``view``, shifted by ``origin_mm``."""

    view: LidarScan | None = field(default=None, repr=False, compare=False)
    origin_mm: tuple[float, float] = (0.0, 0.0)
