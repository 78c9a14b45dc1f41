"""The guard as a live node between a planner and the base, with no ROS dependency.

A :class:`CommandFilter` is the loop of ``docs/robots.md``'s guard node: it keeps the latest scan
(:meth:`~CommandFilter.on_scan`) and pose (:meth:`~CommandFilter.on_pose`), and for each incoming
velocity command (:meth:`~CommandFilter.on_command`) decides what reaches the base:

* ``mode="limit"`` (the default): the command along the same path at the fastest speed whose swept
  body stays clear for ``horizon_s`` (:meth:`Guard.limit_twist <safeembodai_core.Guard.limit_twist>`:
  Nav2's approach scaling, plus any slow-down zones) -- forwarded unchanged, slowed, or a stop;
* ``mode="refuse"``: the command unchanged when the guard accepts it held for ``horizon_s``, else a stop.

A stop also goes out, with its reason, when there is no scan yet or the latest is older than
``scan_timeout_s`` (Nav2's ``source_timeout``: a sensor that stops arriving stops the robot), or a
command's time is earlier than the scan's. A scan older than the one held (a late message) is
refused with a ``ValueError`` naming both times, and the newer one stays: the guard never judges on
an older view of the world than it has had.

Poses place the scan. The pose latest given when a scan arrives is where that scan was taken; when
the robot has moved since (a pose given after it), the rules judge from where the robot now is, in
the scan's own frame (``Guard``'s ``since_scan``: the scan's shadows stay where they are, what it
never saw stays unseen). Without any pose the robot is taken to be where its latest scan was taken
(a scanner on the robot, no odometry). But a scan taken before the first pose cannot be placed once
poses arrive -- the first pose may already be far from where the scan was taken, and guessing it the
same would judge the robot on ground it left -- so every command is stopped, with that reason, until
a new scan arrives (fail closed: at worst one scan period at start-up). Every
:class:`Decision` says why, for the planner. Wire the three methods to your subscriptions (rclpy,
rosbridge, a bag) and publish ``decision.twist``; one filter per robot, not shared between threads.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from collections.abc import Sequence
from typing import Any, Literal

import numpy as np

from ..geometry import relative_pose
from ..ros.laser_scan import LaserScan, SensorMount, finite_number, shown
from ..ros.twist import Twist

STOP = Twist(0.0, 0.0)


@dataclass(frozen=True)
class Decision:
    """What the filter sends for one command: ``action`` (``forward``, ``limit`` or ``stop``), the
    ``twist`` to publish, why (``reasons``, empty when forwarded), the scan's age and the time
    before collision the guard found (None: none within the horizon, or not judged)."""

    action: Literal["forward", "limit", "stop"]
    twist: Twist
    requested: Twist
    time_s: float
    reasons: list[str] = field(default_factory=list)
    scan_age_s: float | None = None
    collision_time_s: float | None = None


class CommandFilter:
    """Per command: limit or refuse by the guard on the latest scan and pose (module docstring)."""

    def __init__(self, guard: Any, *, horizon_s: float = 1.0, scan_timeout_s: float = 0.5,
                 mode: Literal["limit", "refuse"] = "limit", slowdown: Sequence[Any] = (),
                 mount: SensorMount | None = None) -> None:
        self.guard = guard
        self.horizon_s = finite_number("CommandFilter", "horizon_s", horizon_s, "seconds")
        self.scan_timeout_s = finite_number("CommandFilter", "scan_timeout_s", scan_timeout_s, "seconds")
        if self.horizon_s <= 0 or self.scan_timeout_s <= 0:
            raise ValueError(f"CommandFilter needs horizon_s and scan_timeout_s > 0, got {horizon_s!r} and "
                             f"{scan_timeout_s!r}")
        if mode not in ("limit", "refuse"):
            raise ValueError(f"CommandFilter.mode must be 'limit' or 'refuse', got {mode!r}")
        self.mode = mode
        from .twist_judging import SlowdownZone

        self.slowdown = tuple(slowdown)
        for zone in self.slowdown:
            if not isinstance(zone, SlowdownZone):
                raise ValueError(f"CommandFilter.slowdown holds SlowdownZone objects, got {type(zone).__name__}")
        self.mount = mount or SensorMount()
        self._scan: LaserScan | None = None
        self._scan_time: float | None = None
        self._scan_pose: tuple[float, float, float] | None = None
        self._pose: tuple[float, float, float] | None = None

    def on_scan(self, scan: Any, time_s: float) -> None:
        """A new scan: a :class:`LaserScan` or a decoded ``sensor_msgs/LaserScan`` (read with ``mount``),
        taken at ``time_s``; the pose known then is where it was taken. A malformed scan raises
        ``ValueError`` and the last good one stays (and ages towards the timeout)."""
        scan = scan if isinstance(scan, LaserScan) else LaserScan.from_ros(scan, self.mount)
        time_s = finite_number("CommandFilter.on_scan", "time_s", time_s, "seconds")
        if self._scan_time is not None and time_s < self._scan_time:
            raise ValueError(f"CommandFilter.on_scan: a scan taken at {time_s!r} s is older than the one held "
                             f"(taken at {self._scan_time!r} s): the newer one stays")
        self._scan, self._scan_time, self._scan_pose = scan, time_s, self._pose

    @property
    def latest_scan_time(self) -> float | None:
        """When the scan the filter judges on was taken (None: no scan yet)."""
        return self._scan_time

    def on_pose(self, pose: Sequence[float], time_s: float) -> None:
        """The robot's pose ``(x_mm, y_mm, heading_deg)`` in one map frame at ``time_s``: a sequence of
        exactly three numbers (a tuple, a list, an array; not text, bytes, a set or a dict); the latest
        pose given before a scan is where that scan was taken."""
        finite_number("CommandFilter.on_pose", "time_s", time_s, "seconds")
        if isinstance(pose, (str, bytes, bytearray, memoryview)) or not isinstance(pose, (Sequence, np.ndarray)):
            raise ValueError(f"CommandFilter.on_pose: pose must be a sequence (x_mm, y_mm, heading_deg), got "
                             f"{shown(pose)}")
        values = tuple(pose)
        if len(values) != 3:
            raise ValueError(f"CommandFilter.on_pose: pose must be (x_mm, y_mm, heading_deg), got {len(values)} values")
        x, y, heading = (finite_number("CommandFilter.on_pose", name, value)
                         for name, value in zip(("x_mm", "y_mm", "heading_deg"), values))
        self._pose = (x, y, heading)

    @property
    def _scan_unplaced(self) -> bool:
        """Poses arrived after a scan taken with none known: where the robot is relative to it is unknown."""
        return self._scan_pose is None and self._pose is not None

    def _since_scan(self) -> tuple[float, float, float] | None:
        """Where the robot is now in the frame its latest scan was taken in; None when it has not moved
        (or no pose was ever given)."""
        if self._scan_pose is None or self._pose is None or self._pose == self._scan_pose:
            return None
        return relative_pose(self._scan_pose, self._pose)

    def on_command(self, twist: Any, time_s: float) -> Decision:
        """What to send for ``twist`` (a :class:`Twist`, a decoded ``geometry_msgs/Twist`` or a tuple)
        arriving at ``time_s``. A command that cannot be read, or judged (a speed beyond any the guard
        can put in millimetres), is stopped, with the reason naming its field."""
        time_s = finite_number("CommandFilter.on_command", "time_s", time_s, "seconds")
        try:
            requested = self.guard.read_twist(twist)
        except (TypeError, ValueError) as error:
            return Decision("stop", STOP, STOP, time_s, [f"command refused unread: {error}"])
        if self._scan is None or self._scan_time is None:
            return Decision("stop", STOP, requested, time_s, ["no scan yet: stop until one arrives"])
        age = time_s - self._scan_time
        if age > self.scan_timeout_s or age < 0:
            why = (f"the latest scan is {age:.3f} s old (timeout {self.scan_timeout_s:g} s): stop until a new one "
                   "arrives" if age >= 0 else f"the command's time is {-age:.3f} s before the latest scan's")
            return Decision("stop", STOP, requested, time_s, [why], scan_age_s=age)
        if self._scan_unplaced:
            return Decision("stop", STOP, requested, time_s, [
                "the latest scan was taken before any pose was known, and poses have arrived since: where the robot "
                "is relative to that scan is unknown; stop until a new scan arrives"], scan_age_s=age)
        scan, moved = self._scan, self._since_scan()
        try:
            if self.mode == "refuse":
                report = self.guard.check_twist(requested, self.horizon_s, lidar_mm=scan, since_scan=moved)
                if report.valid:
                    return Decision("forward", requested, requested, time_s, scan_age_s=age)
                return Decision("stop", STOP, requested, time_s, report.reasons, age, report.collision_time_s)
            limited = self.guard.limit_twist(requested, self.horizon_s, slowdown=self.slowdown, lidar_mm=scan,
                                             since_scan=moved)
        except (ArithmeticError, ValueError) as error:  # numbers the guard cannot judge: never let them through
            return Decision("stop", STOP, requested, time_s, [f"command refused unjudged: {error}"], age)
        action: Literal["forward", "limit", "stop"] = (
            "forward" if not limited.limited else ("stop" if limited.stopped else "limit"))
        return Decision(action, limited.twist if action != "stop" else STOP, requested, time_s, limited.reasons, age,
                        limited.collision_time_s)


__all__ = ["CommandFilter", "Decision"]
