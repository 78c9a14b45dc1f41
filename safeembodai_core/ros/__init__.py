"""ROS 2 data for the guard, without a ROS install: ``sensor_msgs/LaserScan`` as a plain dataclass.

:class:`LaserScan` holds a scan with ROS semantics (metres, radians, ``range_min``/``range_max``,
``inf``/``nan``) and the sensor's mounting on the robot; :meth:`LaserScan.to_lidar_scan` turns it
into the project's :class:`~safeembodai_core.models.LidarScan` (millimetres, beams evenly round
the robot's centre), which every rule reads. Pass either to :class:`~safeembodai_core.Guard`.
:class:`Twist` is a ``geometry_msgs/Twist`` velocity command; ``Guard.check_twist`` judges it held
for a while and says the time before collision; ``Guard.limit_twist`` slows it instead.
:class:`CommandFilter` is a live guard node's loop (latest scan and pose, per command: forward,
slow or stop), imported on first use.
"""

from typing import Any

from .laser_scan import LaserScan, SensorMount
from .twist import Twist, arc_signals

__all__ = ["CommandFilter", "Decision", "LaserScan", "SensorMount", "Twist", "arc_signals"]


def __getattr__(name: str) -> Any:
    if name in ("CommandFilter", "Decision"):
        from . import command_filter

        return getattr(command_filter, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
