"""ROS 2 data for the guard, without a ROS install: ``sensor_msgs/LaserScan`` as a plain dataclass.

:class:`LaserScan` holds a scan with ROS semantics (metres, radians, ``range_min``/``range_max``,
``inf``/``nan``) and the sensor's mounting on the robot; :meth:`LaserScan.to_lidar_scan` turns it
into the project's :class:`~safeembodai_core.models.LidarScan` (millimetres, beams evenly round
the robot's centre), which every rule reads. Pass either to :class:`~safeembodai_core.Guard`.
:class:`Twist` is a ``geometry_msgs/Twist`` velocity command; ``Guard.check_twist`` judges it held
for a while and says the time before collision; ``Guard.limit_twist`` slows it instead.
:class:`CommandFilter` is a live guard node's loop (latest scan and pose, per command: forward,
slow or stop), imported on first use. Both read messages decoded or as rosbridge sends them (dicts of
their JSON; ``LaserScan.from_ros(..., null_range=...)`` says how a ``null`` range is read).
:func:`read_robot_file` reads a robot file (:class:`RobotFile`: the body, the scanners' mounts and
``null_range``, the velocity limits), imported on first use.
"""

from typing import Any

from .laser_scan import LaserScan, NullRange, SensorMount
from .twist import Twist, arc_signals

__all__ = ["CommandFilter", "Decision", "LaserScan", "NullRange", "RobotFile", "SensorMount", "Twist", "arc_signals",
           "read_robot_file"]


def __getattr__(name: str) -> Any:
    if name in ("CommandFilter", "Decision"):
        from ..guard import command_filter

        return getattr(command_filter, name)
    if name in ("RobotFile", "read_robot_file"):
        from . import robot_file

        return getattr(robot_file, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
