"""ROS 2 data for the guard, without a ROS install: ``sensor_msgs/LaserScan`` as a plain dataclass.

:class:`LaserScan` holds a scan with ROS semantics (metres, radians, ``range_min``/``range_max``,
``inf``/``nan``) and the sensor's mounting on the robot; :meth:`LaserScan.to_lidar_scan` turns it
into the project's :class:`~safeembodai_core.models.LidarScan` (millimetres, beams evenly round
the robot's centre), which every rule reads. Pass either to :class:`~safeembodai_core.Guard`.
:class:`Twist` is a ``geometry_msgs/Twist`` velocity command; ``Guard.check_twist`` judges it held
for a while, as the arc it sweeps (:func:`arc_signals`), and says the longest safe duration.
"""

from .laser_scan import LaserScan, SensorMount
from .twist import Twist, arc_signals

__all__ = ["LaserScan", "SensorMount", "Twist", "arc_signals"]
