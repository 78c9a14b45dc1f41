"""The guard between a planner and the base: what ``safeembodai guard-node`` decides, off the wire.

:class:`GuardNode` takes messages as rosbridge delivers them (dicts) with the time they arrived on
this machine's monotonic clock, and answers what to send to the base, and why:

* a scan (``sensor_msgs/LaserScan``) is read with the robot file's mount and ``null_range`` for its
  topic, and kept; odometry (``nav_msgs/Odometry``) gives the pose the guard judges from since that
  scan (:class:`~safeembodai_core.ros.CommandFilter`'s ``since_scan``);
* a command (``geometry_msgs/Twist`` or ``TwistStamped``) becomes the node's target, held for the
  robot file's ``cmd_vel_timeout_s``; each :meth:`GuardNode.cycle` (on a command, and on the node's
  timer) sends the target through the velocity smoother (:mod:`.smoother`) and then the filter
  (forward, slowed, or a stop) -- Nav2's order: smoother, then collision monitor;
* a stop goes out, with its reason, when the scan goes stale (``scan_timeout_s``, Nav2's
  ``source_timeout``), even with no new command, and when commands stop coming for the timeout.

Ages are measured by arrival on this machine, not by the messages' stamps (ours, because a
rosbridge client and the robot rarely share a synchronised clock; the wire's latency counts against
the scan's age, which errs towards a stop). Nothing raises out of the node: a message that cannot be
read is logged and counted (a bad scan leaves the last good one to age out; a bad command is a stop),
and any failure while deciding is a stop with the error as its reason.
"""

from __future__ import annotations

import json
import math
import threading
from dataclasses import dataclass, field
from typing import Any, Literal

import structlog

from ..geometry.frames import quaternion_yaw_deg
from ..guard.command_filter import CommandFilter, Decision
from ..ros.laser_scan import LaserScan
from ..ros.robot_file import RobotFile
from ..ros.twist import Twist
from .smoother import Smoother

log = structlog.get_logger(__name__)

STOP = Twist(0.0, 0.0)


def twist_message(twist: Twist) -> dict[str, Any]:
    """``geometry_msgs/msg/Twist`` as rosbridge's JSON."""
    return {"linear": {"x": twist.linear_x, "y": twist.linear_y, "z": 0.0},
            "angular": {"x": 0.0, "y": 0.0, "z": twist.angular_z}}


def pose_of_odometry(message: Any) -> tuple[float, float, float]:
    """``(x_mm, y_mm, heading_deg)`` of a ``nav_msgs/Odometry`` dict (planar yaw of its quaternion);
    ``ValueError`` naming the field when it is not one."""
    from ..ros.laser_scan import finite_number

    try:
        pose = message["pose"]["pose"]
        position, orientation = pose["position"], pose["orientation"]
        x = finite_number("Odometry", "pose.pose.position.x", position["x"])
        y = finite_number("Odometry", "pose.pose.position.y", position["y"])
        qx, qy, qz, qw = (finite_number("Odometry", f"pose.pose.orientation.{k}", orientation[k]) for k in "xyzw")
    except (KeyError, TypeError):
        raise ValueError("not a nav_msgs/Odometry: no pose.pose.position and orientation") from None
    norm = math.sqrt(qx * qx + qy * qy + qz * qz + qw * qw)
    if not 0.5 < norm < 1.5:
        raise ValueError(f"Odometry pose.pose.orientation is not a rotation (norm {norm:.3g})")
    return x * 1000.0, y * 1000.0, quaternion_yaw_deg(qx, qy, qz, qw)


@dataclass(frozen=True)
class Sent:
    """One cycle's output: the twist for the base and the decision's record for ``/safeembodai/guard``."""

    twist: Twist
    action: Literal["forward", "limit", "stop"]
    reasons: list[str] = field(default_factory=list)
    collision_time_s: float | None = None
    requested: Twist | None = None

    def record(self, time_s: float) -> dict[str, Any]:
        """The decision as ``std_msgs/msg/String`` JSON (action, reasons, time before collision)."""
        body = {"action": self.action, "reasons": self.reasons, "time_before_collision_s": self.collision_time_s,
                "sent": {"linear_x": self.twist.linear_x, "angular_z": self.twist.angular_z},
                "requested": None if self.requested is None else {"linear_x": self.requested.linear_x,
                                                                   "angular_z": self.requested.angular_z},
                "time_s": round(time_s, 4)}
        return {"data": json.dumps(body, sort_keys=True)}


class GuardNode:
    """The guard's decisions on the wire (module docstring); thread-safe (one lock)."""

    def __init__(self, guard: Any, robot: RobotFile, *, scan_topic: str | None = None, mode: str = "limit",
                 horizon_s: float = 1.0, scan_timeout_s: float = 0.5, period_s: float = 0.05) -> None:
        self.robot = robot
        self.scan_topic = scan_topic or robot.scan_topic
        self.null_range = robot.null_range(self.scan_topic)
        self.mount = robot.mount(self.scan_topic)
        self.filter = CommandFilter(guard, horizon_s=horizon_s, scan_timeout_s=scan_timeout_s,
                                    mode=mode, mount=self.mount)  # type: ignore[arg-type]
        self.smoother = Smoother(robot.velocity_smoother, period_s)
        self.period_s = period_s
        self.scan_timeout_s = scan_timeout_s
        self.judgments = 0
        self._judged_at: float | None = None
        self.command_timeout_s = float(robot.cmd_vel_timeout_s)
        self.target: Twist | None = None
        self.target_at: float | None = None
        self.unread = {"scan": 0, "odom": 0, "command": 0}
        self._lock = threading.Lock()

    def on_scan(self, message: Any, time_s: float) -> None:
        """A scan arrived at ``time_s``; an unreadable one is logged and the last good one ages on."""
        with self._lock:
            try:
                scan = LaserScan.from_ros(message, self.mount, null_range=self.null_range)
                self.filter.on_scan(scan, time_s)
            except (TypeError, ValueError, OverflowError) as error:
                self.unread["scan"] += 1
                log.warning("guard_node.scan_unread", error=str(error)[:300])

    def on_odom(self, message: Any, time_s: float) -> None:
        """Odometry arrived at ``time_s``: where the robot is now (unreadable: logged, ignored)."""
        with self._lock:
            try:
                self.filter.on_pose(pose_of_odometry(message), time_s)
            except (TypeError, ValueError, OverflowError) as error:
                self.unread["odom"] += 1
                log.warning("guard_node.odom_unread", error=str(error)[:300])

    def on_command(self, message: Any, time_s: float) -> Sent:
        """A command arrived at ``time_s``: it becomes the target, and a cycle runs at once. One that
        cannot be read clears the target: the answer is a stop saying why."""
        with self._lock:
            try:
                requested = self.filter.guard.read_twist(message)
            except (TypeError, ValueError, OverflowError) as error:
                self.unread["command"] += 1
                self.target = self.target_at = None
                return self._send(Sent(STOP, "stop", [f"command refused unread: {str(error)[:300]}"]), time_s)
            self.target, self.target_at = requested, time_s
            sent = self._cycle(time_s)
            assert sent is not None  # a target is held: a cycle always answers it
            return sent

    def cycle(self, time_s: float) -> Sent | None:
        """The timer's cycle: the held target again (smoothed, judged on the latest scan), a stop once
        it has run out or the scan has gone stale; None when the base stands and nothing is held, or
        when a command was judged within the last period on a scan still fresh (a planner publishing
        at the node's rate is judged once per command, not twice)."""
        with self._lock:
            scan_time = self.filter.latest_scan_time
            if (self.target is not None and self.target_at is not None and self._judged_at is not None
                    and time_s - self._judged_at < self.period_s and scan_time is not None
                    and time_s - scan_time <= self.scan_timeout_s
                    and time_s - self.target_at <= self.command_timeout_s):
                return None
            return self._cycle(time_s)

    def _cycle(self, time_s: float) -> Sent | None:
        if self.target is None or self.target_at is None:
            return None if self.smoother.sent == STOP else self._send(
                Sent(STOP, "stop", ["no command held"]), time_s)
        if time_s - self.target_at > self.command_timeout_s:
            self.target = self.target_at = None
            return self._send(Sent(STOP, "stop", [f"no command for {self.command_timeout_s:g} s: stop"]), time_s)
        requested = self.target
        self._judged_at = time_s
        self.judgments += 1
        try:
            smoothed = self.smoother.smooth(requested, time_s)
            decision: Decision = self.filter.on_command(smoothed, time_s)
        except Exception as error:  # noqa: BLE001 - whatever fails, the base gets a stop, never nothing
            log.error("guard_node.decision_failed", error=repr(error)[:300])
            return self._send(Sent(STOP, "stop", [f"the guard failed to decide: {str(error)[:200]}"], None,
                                   requested), time_s)
        reasons = list(decision.reasons)
        if smoothed != requested and decision.action != "stop":
            reasons.insert(0, f"velocity smoother: {requested.linear_x:.3f} m/s, {requested.angular_z:.3f} rad/s "
                              f"-> {smoothed.linear_x:.3f} m/s, {smoothed.angular_z:.3f} rad/s")
        action = decision.action if decision.action != "forward" or smoothed == requested else "limit"
        return self._send(Sent(decision.twist, action, reasons, decision.collision_time_s, requested), time_s)

    def _send(self, sent: Sent, time_s: float) -> Sent:
        self.smoother.sent_now(sent.twist, time_s)
        return sent
