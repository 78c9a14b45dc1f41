"""The served room's readings as rosbridge sends ROS 2 messages: JSON objects, SI units.

What a real driver would publish, so that a client reads the room as it reads a robot:

* ``sensor_msgs/msg/LaserScan`` -- the room's LiDAR in metres, counter-clockwise from the heading
  (``angle_min`` 0, beam ``k`` at ``k * angle_increment``), ``range_min``/``range_max`` set; a beam
  with no return within range is ``+inf`` as REP 117 says, which rosbridge's JSON writes as ``null``;
* ``nav_msgs/msg/Odometry`` -- the pose in the room's frame (``odom``: the room's own corner, no
  drift: the simulator knows where the robot is) and the velocity the base is driving;
* ``sensor_msgs/msg/CompressedImage`` -- the camera as JPEG, its bytes in base64 (rosbridge's
  encoding of ``uint8[]``);
* ``std_msgs/msg/String`` -- an event as JSON text.
"""

from __future__ import annotations

import base64
import json
import math
from typing import Any

import cv2
import numpy as np

from ..geometry.frames import yaw_quaternion
from ..models import LidarScan, Pose

LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
STRING = "std_msgs/msg/String"
TWIST = "geometry_msgs/msg/Twist"
TWIST_STAMPED = "geometry_msgs/msg/TwistStamped"
#: The nearest range a scan reports (metres): closer returns are the scanner's blind zone.
RANGE_MIN_M = 0.02
JPEG_QUALITY = 85


def header(time_s: float, frame_id: str) -> dict[str, Any]:
    """A ``std_msgs/msg/Header`` at ``time_s`` seconds of the room's clock."""
    sec = math.floor(time_s)
    return {"stamp": {"sec": int(sec), "nanosec": min(int(round((time_s - sec) * 1e9)), 999_999_999)},
            "frame_id": frame_id}


def laser_scan(scan: LidarScan, time_s: float, period_s: float, frame_id: str = "base_scan") -> dict[str, Any]:
    """The room's scan as ``sensor_msgs/msg/LaserScan`` (module docstring); ``period_s``: the time
    between scans."""
    ranges_mm = np.asarray(scan.ranges_mm, dtype=float)
    count = int(ranges_mm.size)
    increment = 2 * math.pi / count
    range_max = scan.max_range_mm / 1000.0
    ranges: list[float | None] = []
    for value in ranges_mm / 1000.0:
        # +inf (no return within range) and nan (no reading) are both null on rosbridge's wire
        ranges.append(round(float(value), 4) if math.isfinite(value) else None)
    return {"header": header(time_s, frame_id), "angle_min": 0.0, "angle_max": increment * (count - 1),
            "angle_increment": increment, "time_increment": 0.0, "scan_time": period_s,
            "range_min": RANGE_MIN_M, "range_max": range_max, "ranges": ranges, "intensities": []}


def quaternion_z(heading_deg: float) -> dict[str, float]:
    """The rotation about z by ``heading_deg`` as a ``geometry_msgs/msg/Quaternion``."""
    return dict(zip("xyzw", yaw_quaternion(heading_deg)))


def odometry(pose: Pose, linear_m_s: float, angular_rad_s: float, time_s: float) -> dict[str, Any]:
    """The pose (mm and degrees in the room's frame, as metres and a quaternion) and the velocity
    the base drives, as ``nav_msgs/msg/Odometry``."""
    zeros = [0.0] * 36
    return {"header": header(time_s, "odom"), "child_frame_id": "base_link",
            "pose": {"pose": {"position": {"x": pose.x_mm / 1000.0, "y": pose.y_mm / 1000.0, "z": 0.0},
                              "orientation": quaternion_z(pose.heading_deg)}, "covariance": zeros},
            "twist": {"twist": {"linear": {"x": linear_m_s, "y": 0.0, "z": 0.0},
                                "angular": {"x": 0.0, "y": 0.0, "z": angular_rad_s}}, "covariance": zeros}}


def compressed_image(rgb: np.ndarray, time_s: float, frame_id: str = "camera") -> dict[str, Any]:
    """An RGB frame as a JPEG ``sensor_msgs/msg/CompressedImage``, its data in base64."""
    ok, encoded = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])
    if not ok:  # pragma: no cover - OpenCV encodes any uint8 frame
        raise ValueError("the camera frame could not be encoded as JPEG")
    return {"header": header(time_s, frame_id), "format": "jpeg",
            "data": base64.b64encode(encoded.tobytes()).decode("ascii")}


def event(kind: str, time_s: float, **facts: Any) -> dict[str, Any]:
    """An event as ``std_msgs/msg/String`` whose ``data`` is JSON: ``{"event": kind, "time_s": ..., ...}``."""
    return {"data": json.dumps({"event": kind, "time_s": round(time_s, 4), **facts}, sort_keys=True)}
