"""What a :class:`~safeembodai_core.Guard` is given, as declared types; the robot's senses read once.

Commands, held velocities, replies and rules have their declared unions here. Every judging method of
the Guard takes the same sensor keywords (:data:`SENSOR_KEYWORDS`) with the same meaning and defaults,
and :class:`Sensing` reads them once: a scan as a ROS ``LaserScan``, a :class:`LidarScan` or ranges in
millimetres; a pose as a :class:`Pose`, a mapping of its fields or ``(x_mm, y_mm, heading_deg)``;
times on the robot's clock. Anything else, a non-finite number or a value too large for a float, is a
``ValueError`` naming the keyword: never an unjudged command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence, TypeAlias, Union

import numpy as np

from ..models import LidarScan, Pose, Straight, Turn
from ..models.reply import BackendReply
from ..plugin.refs import ComponentRef
from ..ros import LaserScan, Twist
from ..validation.context import Validator
from ..ros.laser_scan import finite_number

#: a scan: ROS semantics (:class:`~safeembodai_core.ros.LaserScan`), the contract's :class:`LidarScan`, or
#: ranges in mm, beam k at k*360/N degrees counter-clockwise from the heading (``inf`` no return, ``nan`` no
#: reading); None: no scan
ScanInput: TypeAlias = Union[LaserScan, LidarScan, Sequence[float], np.ndarray, None]
#: a pose in your map's frame: a :class:`Pose`, a mapping of its fields, or ``(x_mm, y_mm, heading_deg)``
PoseInput: TypeAlias = Union[Pose, Mapping[str, float], Sequence[float], None]

#: a command as the LLM writes it (a mapping) or a signal model
CommandInput: TypeAlias = Union[Mapping[str, Any], Straight, Turn]
#: a held velocity: a :class:`~safeembodai_core.ros.Twist`, a decoded ``geometry_msgs/Twist`` (a mapping) or
#: ``(linear_x m/s, angular_z rad/s[, linear_y m/s])``
TwistInput: TypeAlias = Union[Twist, Mapping[str, Any], Sequence[float]]
#: an LLM's reply: a :class:`~safeembodai_core.models.BackendReply`, a mapping of its fields, or the answer text
ReplyInput: TypeAlias = Union[BackendReply, Mapping[str, Any], str]
#: a rule: a registered validator's name, a mapping ``{use: NAME, options: {...}}``, a reference, or a
#: :class:`~safeembodai_core.Validator` object
RuleInput: TypeAlias = Union[str, Mapping[str, Any], ComponentRef, Validator]

#: the sensor keywords every judging method of the Guard takes, with their defaults
SENSOR_KEYWORDS: dict[str, Any] = {"lidar_mm": None, "max_range_mm": 10_000.0, "pose": None, "time_s": None,
                                   "answer_time_s": None, "since_scan": None, "keep_scan": True}


def read_pose(name: str, pose: PoseInput) -> Pose | None:
    """``pose`` as a finite :class:`Pose`, None for None; ``ValueError`` naming ``name`` otherwise."""
    if pose is None:
        return None
    try:
        if isinstance(pose, Pose):
            read = pose
        elif isinstance(pose, Mapping):
            read = Pose.model_validate(dict(pose))
        elif isinstance(pose, (str, bytes)):
            raise TypeError("text")
        else:
            read = Pose(**dict(zip(("x_mm", "y_mm", "heading_deg"), pose, strict=True)))
    except (TypeError, ValueError, OverflowError) as error:
        raise ValueError(f"{name} must be a Pose, a mapping of its fields or (x_mm, y_mm, heading_deg), "
                         f"got {type(pose).__name__}: {error}") from None
    if not all(math.isfinite(v) for v in (read.x_mm, read.y_mm, read.heading_deg)):
        raise ValueError(f"{name} must be finite, got {read!r}")
    return read


def read_scan(scan: ScanInput, max_range_mm: float) -> LidarScan | None:
    """``scan`` in the contract's terms (a ROS scan converted with its mounting), None for None."""
    if scan is None:
        return None
    if isinstance(scan, LaserScan):
        return scan.to_lidar_scan()  # ROS semantics and the sensor's mounting: safeembodai_core.ros
    if isinstance(scan, LidarScan):
        return scan
    max_range = finite_number("", "max_range_mm", max_range_mm, "mm")
    if isinstance(scan, (str, bytes, Mapping)):
        raise ValueError(f"lidar_mm must be ranges in mm, a LidarScan or a LaserScan, got {type(scan).__name__}")
    try:
        ranges = np.asarray(scan, dtype=float)
    except (TypeError, ValueError, OverflowError) as error:  # 10**400 does not fit a float: refused, not inf
        raise ValueError(f"lidar_mm must be numbers in mm: {error}") from None
    return LidarScan(ranges, max_range)


@dataclass(frozen=True)
class Sensing:
    """The sensor keywords of one judging call, read once (see the module docstring)."""

    scan: LidarScan | None
    pose: Pose | None
    time_s: float | None
    answer_time_s: float | None
    since_scan: Pose | None

    @classmethod
    def read(cls, lidar_mm: ScanInput = None, max_range_mm: float = 10_000.0, pose: PoseInput = None,
             time_s: float | None = None, answer_time_s: float | None = None,
             since_scan: PoseInput = None) -> Sensing:
        scan = read_scan(lidar_mm, max_range_mm)
        start = read_pose("pose", pose)
        if time_s is not None:
            time_s = finite_number("", "time_s", time_s, "seconds")
        if answer_time_s is not None:
            if time_s is None:
                raise ValueError("answer_time_s needs time_s: the scan's time on the same clock")
            answer_time_s = finite_number("", "answer_time_s", answer_time_s, "seconds")
            if answer_time_s < time_s:
                raise ValueError(f"answer_time_s must be finite and not before time_s ({time_s:g}), "
                                 f"got {answer_time_s!r}")
        return cls(scan, start, time_s, answer_time_s, read_pose("since_scan", since_scan))
