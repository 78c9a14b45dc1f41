"""What guard-mcp knows of the robot: its own latest scan and odometry, read over rosbridge.

:class:`RobotSenses` subscribes to the robot file's scan topic and the policy's odometry topic with a
rosbridge client of its own (never from the agent's text, never through the upstream MCP server) and
keeps the latest of each with the time it arrived on this machine's monotonic clock, as guard-node
does. :meth:`RobotSenses.view` answers what a judgement needs -- the scan, its age, and where the
robot is now in the scan's frame (odometry since the scan) -- or raises :class:`Blind` when there is
no scan yet, the latest is older than the policy's ``scan_timeout_s``, or the connection is lost.

It also sends the guard's own stops: a refused slice of a running motion is followed at once by a
zero velocity published on this connection, not through the upstream.
"""

from __future__ import annotations

import threading
import time
from dataclasses import dataclass
from typing import Any, Callable

from ..geometry import relative_pose
from ..guard_node.node import pose_of_odometry
from ..logs import get_logger
from ..ros.laser_scan import LaserScan
from ..ros.robot_file import RobotFile

log = get_logger(__name__)
LASER_SCAN = "sensor_msgs/msg/LaserScan"
ODOMETRY = "nav_msgs/msg/Odometry"
ZERO = {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}


class Blind(Exception):
    """No judgement is possible: no scan yet, a stale one, or no connection; the text says which."""


@dataclass(frozen=True)
class View:
    """The latest scan, its age, and the robot's pose now in the scan's frame (None: not moved, or no odometry)."""

    scan: LaserScan
    age_s: float
    since_scan: tuple[float, float, float] | None
    pose: tuple[float, float, float] | None


class RobotSenses:
    """The robot's own scan and odometry (module docstring); thread-safe."""

    def __init__(self, robot: RobotFile, *, scan_timeout_s: float, odom_topic: str | None = "/odom",
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.scan_topic, self.odom_topic = robot.scan_topic, odom_topic
        self.mount, self.null_range = robot.mount(), robot.null_range()
        self.scan_timeout_s, self.clock = scan_timeout_s, clock
        self.unread = {"scan": 0, "odom": 0}
        self.lost: str | None = None
        self.client: Any = None
        self._scan: tuple[LaserScan, float, tuple[float, float, float] | None] | None = None
        self._pose: tuple[float, float, float] | None = None
        self._advertised: dict[str, str] = {}
        self._lock = threading.Lock()

    def connect(self, url: str) -> RobotSenses:
        """Subscribe over rosbridge at ``url``; ``RosbridgeError`` when it cannot be reached."""
        from ..rosbridge.client import RosbridgeClient

        self.client = RosbridgeClient(url, on_close=self._lost).connect()
        self.client.subscribe(self.scan_topic, LASER_SCAN, self.on_scan, queue_length=1)
        if self.odom_topic:
            self.client.subscribe(self.odom_topic, ODOMETRY, self.on_odom, queue_length=1)
        return self

    def _lost(self, why: str) -> None:
        self.lost = why
        log.error("guard_mcp.rosbridge_lost", why=why, advice="every motion is refused until guard-mcp restarts")

    def on_scan(self, message: Any, time_s: float | None = None) -> None:
        """A scan arrived (now, or at ``time_s``); an unreadable one is logged and the last good one ages on."""
        at = self.clock() if time_s is None else time_s
        try:
            scan = LaserScan.from_ros(message, self.mount, null_range=self.null_range)
        except (TypeError, ValueError, OverflowError) as error:
            self.unread["scan"] += 1
            log.warning("guard_mcp.scan_unread", error=str(error)[:300])
            return
        with self._lock:
            self._scan = (scan, at, self._pose)

    def on_odom(self, message: Any, time_s: float | None = None) -> None:
        """Odometry arrived: where the robot is now (an unreadable one is logged, ignored)."""
        try:
            pose = pose_of_odometry(message)
        except (TypeError, ValueError, OverflowError) as error:
            self.unread["odom"] += 1
            log.warning("guard_mcp.odom_unread", error=str(error)[:300])
            return
        with self._lock:
            self._pose = pose

    @property
    def pose(self) -> tuple[float, float, float] | None:
        """The latest odometry pose ``(x_mm, y_mm, heading_deg)``, None before any."""
        with self._lock:
            return self._pose

    def view(self, now: float | None = None) -> View:
        """What the next judgement is made on (module docstring); :class:`Blind` when nothing can be judged."""
        now = self.clock() if now is None else now
        if self.lost is not None:
            raise Blind(f"the connection to the robot's rosbridge is lost ({self.lost}): nothing can be judged")
        with self._lock:
            latest, pose = self._scan, self._pose
        if latest is None:
            raise Blind(f"no scan yet on {self.scan_topic}: nothing can be judged until one arrives")
        scan, at, scan_pose = latest
        age = now - at
        if age > self.scan_timeout_s:
            raise Blind(f"the latest scan on {self.scan_topic} is {age:.2f} s old (scan_timeout_s "
                        f"{self.scan_timeout_s:g}): nothing can be judged until a new one arrives")
        moved = None if scan_pose is None or pose is None or pose == scan_pose else relative_pose(scan_pose, pose)
        return View(scan, max(age, 0.0), moved, pose)

    def stop(self, topic: str, msg_type: str) -> None:
        """Publish a zero velocity of ``msg_type`` on ``topic`` now, on this connection (errors logged)."""
        if self.client is None:
            return
        try:
            if self._advertised.get(topic) != msg_type:
                if topic in self._advertised:
                    self.client.unadvertise(topic)
                self.client.advertise(topic, msg_type)
                self._advertised[topic] = msg_type
            stamped = msg_type.endswith("TwistStamped")
            self.client.publish(topic, {"header": {"frame_id": ""}, "twist": ZERO} if stamped else ZERO)
        except Exception as error:  # noqa: BLE001 - a stop that cannot be sent is logged; the base's timeout stops it
            log.error("guard_mcp.stop_failed", topic=topic, error=str(error)[:300])

    def close(self) -> None:
        if self.client is not None:
            self.client.close()
            self.client = None
