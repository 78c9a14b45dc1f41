"""A recorded robot through the guard: which commands of a ROS 2 bag would the guard have refused?

:func:`guard_bag` reads a bag with ``rosbags`` (rosbag2 in MCAP or SQLite, or ROS 1), walks the
command topic in log-time order and judges each command with the latest scan (and pose) logged
before it, through :class:`~safeembodai_core.Guard` -- the same rules, the same code as a live check:

* ``geometry_msgs/Twist`` or ``TwistStamped``: the arc the command sweeps while held until the next
  command on the topic (at most ``max_hold_s``), or for ``hold_s`` when given
  (:meth:`~safeembodai_core.Guard.check_twist`; a refusal says the longest safe duration);
* ``std_msgs/String`` holding a plan as JSON -- ``{"control": [...]}`` as ``safeembodai export``
  writes on ``/safeembodai/plan``, or the list of signals alone: judged as the LLM's plan
  (:meth:`~safeembodai_core.Guard.check`); a plan that recorded no control (the answer did not
  parse) is refused with the recorded reason.

A scan is ``sensor_msgs/LaserScan`` (:class:`~safeembodai_core.ros.LaserScan`, with the sensor's
``mount``). A pose topic, optional (``geometry_msgs/PoseStamped``, metres, one map frame), does two
things: a command given after the robot moved on from its latest scan is judged from where the
robot now is, in that scan's own frame (``Guard``'s ``since_scan``: the scan's shadows and unread
directions stay unseen), and rules about motion get the earlier scans as history -- only from a
scan taken where the robot stands, since an old scan is no new look at the movers. Without a pose
topic every command is judged with the latest scan as if the robot were where it took it. Bad
input is an error naming the bag, the topic and the message -- a missing topic, a topic of
another type, a scan with zero beams or a NaN increment, a Twist with NaN -- and nothing is
reported for a bag that has one.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Iterator

from ..errors import SafeEmbodAIError
from ..models.strict_json import read_json_document
from ..geometry import relative_pose
from ..ros.laser_scan import LaserScan, SensorMount
from ..ros.twist import Twist
from ..ros import messages as m
from ..geometry.frames import wrap_deg

SCAN_TYPES = ("sensor_msgs/msg/LaserScan",)
TWIST_TYPES = ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped")
PLAN_TYPES = ("std_msgs/msg/String",)
POSE_TYPES = ("geometry_msgs/msg/PoseStamped",)
#: Most characters of a plan message read (a longer one is refused unread).
MAX_PLAN_CHARS = 100_000


class BagInputError(SafeEmbodAIError):
    """The bag cannot be judged as asked (names the bag, topic and message at fault)."""


@dataclass
class CommandVerdict:
    """The guard's verdict on one command of the bag."""

    index: int  # the command's position on its topic, from 0
    time_s: float  # its log time
    kind: str  # "twist" or "plan"
    command: dict[str, Any]
    valid: bool
    reasons: list[str] = field(default_factory=list)
    scan_time_s: float | None = None  # the scan it was judged with (None: no scan logged before it)
    safe_duration_s: float | None = None  # twists: the longest duration every rule accepts
    collision_time_s: float | None = None  # twists: when the swept body would first touch something in the hold
    allowed: dict[str, float] | None = None  # twists, with ``limit``: the fastest command along its path kept clear
    recorded: dict[str, Any] | None = None  # plans exported by safeembodai: the verdict recorded in the trial

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass
class BagReport:
    """What :func:`guard_bag` found: one verdict per command, and what it read."""

    bag: str
    scan_topic: str
    cmd_topic: str
    pose_topic: str | None
    rules: list[str]
    verdicts: list[CommandVerdict]

    @property
    def refused(self) -> list[CommandVerdict]:
        return [v for v in self.verdicts if not v.valid]

    def as_dict(self) -> dict[str, Any]:
        return {"bag": self.bag, "scan_topic": self.scan_topic, "cmd_topic": self.cmd_topic,
                "pose_topic": self.pose_topic, "rules": self.rules, "commands": len(self.verdicts),
                "refused": len(self.refused), "verdicts": [v.as_dict() for v in self.verdicts]}


def open_bag(path: str | Path) -> Any:
    """An open ``rosbags`` reader of ``path`` (a rosbag2 folder, or a ROS 1 ``.bag``), or a clear error."""
    from rosbags.highlevel import AnyReader

    bag = Path(path)
    if not bag.exists():
        raise BagInputError(f"{bag}: no such bag")
    try:
        reader = AnyReader([bag], default_typestore=m.typestore())
        reader.open()
    except Exception as error:  # rosbags' own errors: not a bag, unreadable metadata, unknown storage
        raise BagInputError(f"{bag}: cannot be read as a ROS bag ({type(error).__name__}: {error})") from None
    return reader


def _connection(reader: Any, bag: Path, topic: str, allowed: tuple[str, ...], role: str) -> list[Any]:
    found = [c for c in reader.connections if c.topic == topic]
    if not found:
        topics = sorted({f"{c.topic} ({c.msgtype})" for c in reader.connections})
        raise BagInputError(f"{bag}: no topic {topic!r} for the {role}; the bag has: {', '.join(topics) or 'none'}")
    wrong = [c.msgtype for c in found if c.msgtype not in allowed]
    if wrong:
        raise BagInputError(f"{bag}: topic {topic!r} carries {wrong[0]}, not a {role} ({' or '.join(allowed)})")
    return found


def _plan(text: str) -> tuple[Any, dict[str, Any] | None]:
    """The control list of a plan message, and what the export recorded of it (or None)."""
    if len(text) > MAX_PLAN_CHARS:
        raise ValueError(f"a plan message of {len(text)} characters (more than {MAX_PLAN_CHARS})")
    # the LLM answers' strict reading: a duplicate key, 1e309 or NaN is refused, not judged last-one-wins
    payload = read_json_document(text, "the plan message")
    if isinstance(payload, list):
        return payload, None
    if isinstance(payload, dict) and "control" in payload:
        recorded = {k: payload[k] for k in ("step", "attempt", "accepted", "parse_error", "verdicts") if k in payload}
        return payload["control"], recorded or None
    raise ValueError('a plan must be a JSON list of signals or an object with "control"')


def _pose_of(message: Any) -> tuple[float, float, float]:
    p = message.pose
    values = (p.position.x * 1000.0, p.position.y * 1000.0, m.yaw_deg(p.orientation))
    if not all(math.isfinite(v) for v in values):
        raise ValueError(f"a non-finite pose {values}")
    return values


#: A robot that moved less than this since its scan (mm, degrees) is judged at the scan's pose.
STILL_MM, STILL_DEG = 1.0, 0.1


def _still(scan_pose: tuple[float, float, float] | None, pose: tuple[float, float, float] | None) -> bool:
    """Whether the robot is where it took the scan (both poses unknown counts as still)."""
    if scan_pose is None or pose is None:
        return scan_pose is None and pose is None
    (xs, ys, hs), (xc, yc, hc) = scan_pose, pose
    return math.hypot(xs - xc, ys - yc) < STILL_MM and abs(wrap_deg(hs - hc)) < STILL_DEG


def seen_from(scan: LaserScan, scan_pose: tuple[float, float, float] | None,
              pose: tuple[float, float, float] | None) -> tuple[LaserScan, bool]:
    """``scan`` as the robot at ``pose`` sees it, when it was taken at ``scan_pose`` (both in one map
    frame): the same beams from a sensor mounted where the old scan's sensor now is relative to the
    robot (:meth:`LaserScan.to_lidar_scan` re-bins them; what it never saw stays unknown). Also
    whether the robot is still where it scanned (then the scan is returned unchanged)."""
    if _still(scan_pose, pose):
        return scan, True
    if scan_pose is None or pose is None:
        return scan, False
    (xs, ys, hs), (xc, yc, hc) = scan_pose, pose
    turn = wrap_deg(hs - hc)
    c, s = math.cos(math.radians(-hc)), math.sin(math.radians(-hc))
    dx, dy = xs - xc, ys - yc
    mx, my = scan.mount.x_mm, scan.mount.y_mm
    cs, ss = math.cos(math.radians(hs - hc)), math.sin(math.radians(hs - hc))
    mount = SensorMount(c * dx - s * dy + cs * mx - ss * my, s * dx + c * dy + ss * mx + cs * my,
                        turn + scan.mount.yaw_deg)
    return LaserScan(angle_min=scan.angle_min, angle_increment=scan.angle_increment, ranges=scan.ranges,
                     range_min=scan.range_min, range_max=scan.range_max, angle_max=scan.angle_max, mount=mount), False


def _messages(reader: Any, bag: Path, connections: list[Any]) -> Iterator[tuple[Any, int, Any]]:
    """The messages of ``connections`` in log-time order, decoded; a bag that cannot be read or
    decoded (truncated, corrupt, lying about its types) is a :class:`BagInputError`, not a crash."""
    counts: dict[str, int] = {}
    stream = iter(reader.messages(connections=connections))
    while True:
        where = "after the last message read"
        try:
            item = next(stream, None)
            if item is None:
                return
            connection, ns, raw = item
            where = f"{connection.topic} message {counts.get(connection.topic, 0)} (at {ns / 1e9:.3f} s)"
            counts[connection.topic] = counts.get(connection.topic, 0) + 1
            message = reader.deserialize(raw, connection.msgtype)
        except Exception as error:  # rosbags' own errors, struct and index errors of a corrupt record
            raise BagInputError(f"{bag}: cannot read {where}: {type(error).__name__}: {error}") from None
        yield connection, ns, message


def guard_bag(path: str | Path, guard: Any, *, scan_topic: str = "/scan", cmd_topic: str = "/cmd_vel",
              pose_topic: str | None = None, mount: SensorMount | None = None, hold_s: float | None = None,
              max_hold_s: float = 1.0, min_hold_s: float = 0.1, limit: bool = False) -> BagReport:
    """Judge every command on ``cmd_topic`` of the bag at ``path`` with ``guard`` (module docstring).
    A Twist counts as held until the next command, at least ``min_hold_s`` (a command replaced at
    once still moves the robot for a control period) and at most ``max_hold_s``; ``hold_s`` fixes it.
    With ``limit`` each Twist also gets the speed the guard would have allowed for its hold
    (:meth:`Guard.limit_twist <safeembodai_core.Guard.limit_twist>`: ``allowed``)."""
    if min_hold_s is not None and max_hold_s is not None and min_hold_s > max_hold_s:
        raise BagInputError(f"min_hold_s {min_hold_s!r} is more than max_hold_s {max_hold_s!r}")
    for name, value in (("hold_s", hold_s), ("max_hold_s", max_hold_s), ("min_hold_s", min_hold_s)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise BagInputError(f"{name} must be a positive number of seconds, got {value!r}")
    bag = Path(path)
    reader = open_bag(bag)
    try:
        scans = _connection(reader, bag, scan_topic, SCAN_TYPES, "scan")
        commands = _connection(reader, bag, cmd_topic, TWIST_TYPES + PLAN_TYPES, "command")
        poses = _connection(reader, bag, pose_topic, POSE_TYPES, "pose") if pose_topic else []
        verdicts = list(_judge(reader, bag, guard, scans, commands, poses, scan_topic, cmd_topic, pose_topic,
                               mount, hold_s, max_hold_s, min_hold_s, limit))
    finally:
        reader.close()
    rules = [name for name, _ in guard.rules]
    return BagReport(str(bag), scan_topic, cmd_topic, pose_topic, rules, verdicts)


def _judge(reader, bag, guard, scans, commands, poses, scan_topic, cmd_topic, pose_topic, mount, hold_s,
           max_hold_s, min_hold_s, limit=False) -> Iterator[CommandVerdict]:
    scan: LaserScan | None = None
    scan_time: float | None = None
    scan_pose: tuple[float, float, float] | None = None
    pose: tuple[float, float, float] | None = None
    counts = {scan_topic: 0, cmd_topic: 0, pose_topic: 0}
    pending: tuple[int, float, Twist, LaserScan | None, float | None, Any, bool] | None = None

    def as_seen() -> tuple[LaserScan | None, bool, dict[str, Any]]:
        """The latest scan, whether the robot is still where it took it, and where to judge from:
        with a pose, the scan's pose and (once the robot moved on) where it is now in the scan's frame."""
        if scan is None:
            return None, False, {"pose": pose}
        still = _still(scan_pose, pose)
        if still or scan_pose is None or pose is None:
            return scan, still, {"pose": pose}
        return scan, False, {"pose": scan_pose, "since_scan": relative_pose(scan_pose, pose)}

    def twist_verdict(item, until: float | None) -> CommandVerdict:
        index, time_s, twist, seen, seen_time, at, still = item
        duration = hold_s if hold_s is not None else max(min_hold_s, min(max_hold_s, until - time_s)) \
            if until is not None else max_hold_s
        # history for motion rules only from a scan taken where the robot stands (module docstring)
        judged_at = {"lidar_mm": seen, **at, "time_s": seen_time if at["pose"] is not None and still else None}
        allowed = None
        if limit and duration > 0:
            limited = guard.limit_twist(twist, duration, **judged_at)
            report = limited.report
            allowed = {"linear_x": limited.twist.linear_x, "angular_z": limited.twist.angular_z,
                       "factor": limited.factor}
        else:
            report = guard.check_twist(twist, max(duration, 0.0), **judged_at)
        return CommandVerdict(index=index, time_s=time_s, kind="twist",
                              command={"linear_x": twist.linear_x, "angular_z": twist.angular_z,
                                       "duration_s": report.duration_s},
                              valid=report.valid, reasons=report.reasons, scan_time_s=seen_time,
                              safe_duration_s=report.safe_duration_s, collision_time_s=report.collision_time_s,
                              allowed=allowed)

    for connection, ns, message in _messages(reader, bag, scans + commands + poses):
        topic, time_s = connection.topic, ns / 1e9
        index = counts[topic]
        counts[topic] += 1
        where = f"{bag}: {topic} message {index} (at {time_s:.3f} s)"
        try:
            if topic == scan_topic:
                scan, scan_time, scan_pose = LaserScan.from_ros(message, mount), time_s, pose
            elif topic == pose_topic:
                pose = _pose_of(message)
            elif connection.msgtype in TWIST_TYPES:
                twist = Twist.from_ros(message)
                if pending is not None:
                    yield twist_verdict(pending, time_s)  # judged now that its hold is known
                seen, still, at = as_seen()
                pending = (index, time_s, twist, seen, scan_time, at, still)
            else:
                control, recorded = _plan(message.data)
                seen, still, at = as_seen()
                yield _plan_verdict(guard, index, time_s, control, recorded, seen, scan_time, at, still)
        except (ValueError, ArithmeticError) as error:  # a bad number, or one too large to compute with
            raise BagInputError(f"{where}: {error}") from None
    if pending is not None:
        try:
            yield twist_verdict(pending, None)
        except (ValueError, ArithmeticError) as error:
            raise BagInputError(f"{bag}: {cmd_topic} message {pending[0]} (at {pending[1]:.3f} s): {error}") from None


def _plan_verdict(guard, index, time_s, control, recorded, scan, scan_time, at, still) -> CommandVerdict:
    if control is None:  # the exported answer did not parse: nothing to judge, refused as it was
        reason = (recorded or {}).get("parse_error") or "the message holds no plan"
        return CommandVerdict(index=index, time_s=time_s, kind="plan", command={"control": None}, valid=False,
                              reasons=[f"schema: {reason}"], scan_time_s=scan_time, recorded=recorded)
    if not isinstance(control, list):
        raise ValueError(f'"control" must be a list of signals, got {type(control).__name__}')
    report = guard.check(control, lidar_mm=scan, **at, time_s=scan_time if at["pose"] is not None and still else None)
    return CommandVerdict(index=index, time_s=time_s, kind="plan", command={"control": control}, valid=report.valid,
                          reasons=report.reasons, scan_time_s=scan_time, recorded=recorded)
