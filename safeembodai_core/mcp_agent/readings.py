"""What the agent reads off its read tools: the scan, the camera frame and the text the camera reads.

ros-mcp's ``subscribe_once`` answers ``{"msg": <the ROS message>}`` (an image topic: the frame as an
image part). A server in front of it may wrap that answer (guard-mcp marks upstream results as
untrusted data), so the message is looked for in the structured content, then in the JSON objects
of the text, to a bounded depth. Everything read is checked as a robot's driver output is checked
(:class:`~safeembodai_core.ros.laser_scan.LaserScan`); what cannot be read is :class:`NotRead`, and
the agent decides on what it has (a pilot without a scan sees no LiDAR).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..models import LidarScan
from ..models.strict_json import ResponseParseError, find_objects
from ..ros.laser_scan import LaserScan
from .tools import ToolOutcome

#: How deep a wrapped answer is searched for the message.
MAX_DEPTH = 4
#: The longest text read as what the camera reads.
MAX_TEXT_CHARS = 2000


class NotRead(ValueError):
    """A read tool's answer holds no message of the kind asked for (the reason says why)."""


def _find_message(value: Any, depth: int = 0) -> dict[str, Any] | None:
    if depth > MAX_DEPTH or not isinstance(value, dict):
        return None
    found = value.get("msg")
    if isinstance(found, dict):
        return found
    for inner in value.values():
        if isinstance(inner, dict):
            message = _find_message(inner, depth + 1)
            if message is not None:
                return message
    return None


def ros_message(outcome: ToolOutcome) -> dict[str, Any]:
    """The ROS message a ``subscribe_once`` answer carries (wrapped or not)."""
    if outcome.error:
        raise NotRead(f"{outcome.tool} failed: {outcome.text[:200]}")
    message = _find_message(outcome.structured)
    if message is None and outcome.text:
        try:
            objects = find_objects(outcome.text, most=8)
        except ResponseParseError:
            objects = []
        for found, _, _ in objects:
            message = _find_message(found)
            if message is not None:
                break
    if message is None:
        raise NotRead(f"{outcome.tool} answered no message")
    return message


def laser_scan(outcome: ToolOutcome) -> LidarScan:
    """The ``sensor_msgs/msg/LaserScan`` answer as the rules read a scan (a ``null`` range: no return,
    as REP 117 and the served room say)."""
    try:
        return LaserScan.from_ros(ros_message(outcome), null_range="no_return").to_lidar_scan()
    except (TypeError, ValueError, OverflowError) as error:
        raise NotRead(f"the scan cannot be read: {error}"[:300]) from None


def camera_frame(outcome: ToolOutcome) -> np.ndarray:
    """The first image part of the answer, decoded to RGB (H x W x 3, uint8)."""
    import cv2

    if outcome.error:
        raise NotRead(f"{outcome.tool} failed: {outcome.text[:200]}")
    for _, data in outcome.images:
        frame = cv2.imdecode(np.frombuffer(data, dtype=np.uint8), cv2.IMREAD_COLOR)
        if frame is not None and frame.ndim == 3 and frame.shape[2] == 3:
            return np.ascontiguousarray(frame[..., ::-1])
    raise NotRead(f"{outcome.tool} answered no image that decodes")


def camera_text(outcome: ToolOutcome) -> str:
    """The ``std_msgs/msg/String`` answer's ``data``: what the camera reads (empty: nothing)."""
    data = ros_message(outcome).get("data")
    if not isinstance(data, str):
        raise NotRead("the text the camera reads is not a string")
    return data[:MAX_TEXT_CHARS]
