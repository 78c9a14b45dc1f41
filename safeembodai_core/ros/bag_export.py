"""A trial as a ROS 2 bag (rosbag2: MCAP by default, or SQLite), on simulated time.

One bag per trial, written with ``rosbags`` from the trial's step records and what
:class:`~safeembodai_core.loop.capture.TrialCapture` saw. Topics (:data:`TOPICS`):

* ``/scan`` (``sensor_msgs/LaserScan``, frame ``base_link``) -- each step's scan as the rules read
  it (after any sensor attack), beams counter-clockwise from the heading, ``inf`` for no return;
* ``/camera/image/compressed`` and ``/lidar/image/compressed`` (``sensor_msgs/CompressedImage``) --
  the images the LLM was shown that step (other image modalities: ``/safeembodai/<name>/compressed``);
* ``/pose`` (``geometry_msgs/PoseStamped``, frame ``map``) and ``/tf`` (``map`` -> ``base_link``)
  -- the robot's true pose at each observation and after each command;
* ``/world/markers`` (``visualization_msgs/MarkerArray``, frame ``map``) -- the room, the robot, the
  can, balls and Labbots (the simulator's ground truth), and a mark where a collision happened;
* ``/cmd_vel`` (``geometry_msgs/Twist``) -- each executed command as the velocity it ran at (its
  distance or angle over its simulated duration), and a zero command when it ended;
* ``/safeembodai/plan`` (``std_msgs/String``) -- every attempt's plan as JSON (``step``, ``attempt``,
  ``control``, ``accepted``, ``verdicts``), refused ones included: ``safeembodai guard-bag`` judges
  these again;
* ``/rosout`` (``rcl_interfaces/Log``) -- the LLM's answers (``llm``), refusals and acceptances
  (``guard``), injected attacks (``attacker``), collisions (``world``) and the outcome (``trial``);
* ``/safeembodai/trial`` (``std_msgs/String``) -- the trial's id, seed, robot and rules at the start,
  its result at the end; ``/clock`` (``rosgraph_msgs/Clock``) -- the simulated time.

Every message's log time and header stamp is the simulated time it happened at; events of one
instant are 1 ns apart, in the order they happened (the pose, TF, markers and clock of one event
share its time). Text an LLM or attacker wrote goes out redacted,
with control characters shown as escapes. The bag is written aside and renamed into place: a
failure leaves nothing at the target.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from ..contracts.components import RobotSpec, WorldSnapshot
from ..errors import SafeEmbodAIError
from ..loop.capture import Executed, Observed, Seen, TrialCapture
from ..models import Pose, StepRecord, Straight, TrialResult, TrialSpec
from ..models.observation import LidarScan
from ..trust.text import terminal_text
from . import messages as m

TOPICS = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/pose": "geometry_msgs/msg/PoseStamped",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/lidar/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/world/markers": "visualization_msgs/msg/MarkerArray",
    "/cmd_vel": "geometry_msgs/msg/Twist",
    "/safeembodai/plan": "std_msgs/msg/String",
    "/safeembodai/trial": "std_msgs/msg/String",
    "/rosout": "rcl_interfaces/msg/Log",
}
IMAGE_TOPICS = {"camera_image": "/camera/image/compressed", "lidar_image": "/lidar/image/compressed"}
STORAGES = ("mcap", "sqlite3")
DEBUG, INFO, WARN, ERROR = 10, 20, 30, 40
_COLOURS = {"robot": (0.1, 0.4, 0.9), "can": (0.85, 0.1, 0.1), "ball": (0.9, 0.9, 0.9), "labbot": (1.0, 0.55, 0.0),
            "obstacle": (0.5, 0.5, 0.5), "collision": (1.0, 0.0, 0.0)}
_HEIGHT_M = {"robot": 0.25, "can": 0.12, "ball": 0.22, "labbot": 0.2}
CYLINDER, SPHERE, LINE_STRIP, DELETEALL = 3, 2, 4, 3


class BagWriteError(SafeEmbodAIError):
    """A bag could not be written (names the file and why); nothing is left at the target."""


def image_topic(name: str) -> str:
    return IMAGE_TOPICS.get(name, f"/safeembodai/{name}/compressed")


def _ns(seconds: float) -> int:
    return int(round(max(0.0, float(seconds)) * 1e9))


def _text(value: Any) -> str:
    return terminal_text(str(value), keep_layout=True)


class _Timeline:
    """Messages on one clock: each event later than the one before, by 1 ns at least."""

    def __init__(self) -> None:
        self.last = -1
        self.messages: list[tuple[str, int, Any]] = []

    def at(self, seconds: float) -> int:
        self.last = max(_ns(seconds), self.last + 1)
        return self.last

    def next(self) -> int:
        """The instant right after the last event (1 ns on): for what happens without the clock moving."""
        self.last += 1
        return self.last

    def add(self, topic: str, ns: int, message: Any) -> None:
        self.messages.append((topic, ns, message))


def laser_scan(scan: LidarScan, ns: int) -> Any:
    """A scan in the rules' format (mm, beams evenly round the robot from its heading) as a LaserScan."""
    count = scan.beam_count
    ranges = np.asarray(scan.ranges_mm, dtype=float) / 1000.0
    increment = 2 * math.pi / count
    return m.build("sensor_msgs/msg/LaserScan", header=m.header(ns, "base_link"), angle_min=0.0,
                   angle_max=float(increment * (count - 1)), angle_increment=float(increment),
                   range_min=0.0, range_max=float(scan.max_range_mm / 1000.0),
                   ranges=ranges.astype(np.float32))


def _pose_messages(line: _Timeline, ns: int, pose: Pose) -> None:
    x, y = pose.x_mm / 1000.0, pose.y_mm / 1000.0
    orientation = m.quaternion(pose.heading_deg)
    line.add("/pose", ns, m.build("geometry_msgs/msg/PoseStamped", header=m.header(ns, "map"),
                                  pose=m.build("geometry_msgs/msg/Pose", position=m.point(x, y),
                                               orientation=orientation)))
    transform = m.build("geometry_msgs/msg/Transform", translation=m.vector(x, y), rotation=orientation)
    line.add("/tf", ns, m.build("tf2_msgs/msg/TFMessage", transforms=[
        m.build("geometry_msgs/msg/TransformStamped", header=m.header(ns, "map"), child_frame_id="base_link",
                transform=transform)]))


def _marker(ns: int, space: str, index: int, kind: str, x_mm: float, y_mm: float, radius_mm: float,
            shape: int = CYLINDER) -> Any:
    height = _HEIGHT_M.get(kind, 0.2)
    diameter = max(2 * radius_mm / 1000.0, 0.01)
    return m.build("visualization_msgs/msg/Marker", header=m.header(ns, "map"), ns=space, id=index, type=shape,
                   pose=m.build("geometry_msgs/msg/Pose", position=m.point(x_mm / 1000.0, y_mm / 1000.0, height / 2),
                                orientation=m.quaternion(0.0)),
                   scale=m.vector(diameter, diameter, height if shape == CYLINDER else diameter),
                   color=m.color(*_COLOURS.get(kind, (0.6, 0.3, 0.8))))


def _markers(line: _Timeline, ns: int, world: WorldSnapshot | None, pose: Pose | None, robot: RobotSpec,
             collisions: list[Pose]) -> None:
    markers = [m.build("visualization_msgs/msg/Marker", header=m.header(ns, "map"), action=DELETEALL)]
    if world is not None and world.room_mm:
        side = world.room_mm / 1000.0
        markers.append(m.build("visualization_msgs/msg/Marker", header=m.header(ns, "map"), ns="room", id=0,
                               type=LINE_STRIP, pose=m.build("geometry_msgs/msg/Pose", orientation=m.quaternion(0.0)),
                               scale=m.vector(0.03), color=m.color(0.2, 0.2, 0.2),
                               points=[m.point(0, 0), m.point(side, 0), m.point(side, side), m.point(0, side),
                                       m.point(0, 0)]))
    counts: dict[str, int] = {}
    for item in world.objects if world is not None else ():
        counts[item.kind] = counts.get(item.kind, -1) + 1
        markers.append(_marker(ns, item.kind, counts[item.kind], item.kind, item.x_mm, item.y_mm, item.radius_mm))
    if pose is not None:
        markers.append(_marker(ns, "robot", 0, "robot", pose.x_mm, pose.y_mm, robot.radius_mm))
    for index, where in enumerate(collisions):
        markers.append(_marker(ns, "collision", index, "collision", where.x_mm, where.y_mm, 60.0, SPHERE))
    line.add("/world/markers", ns, m.build("visualization_msgs/msg/MarkerArray", markers=markers))


def _log(line: _Timeline, ns: int, level: int, name: str, text: str) -> None:
    line.add("/rosout", ns, m.build("rcl_interfaces/msg/Log", stamp=m.stamp(ns), level=level, name=name,
                                    msg=_text(text), file="safeembodai", function=name))


def _string(line: _Timeline, topic: str, ns: int, payload: dict[str, Any]) -> None:
    line.add(topic, ns, m.build("std_msgs/msg/String", data=json.dumps(payload, ensure_ascii=True)))


def _velocity(item: Executed) -> tuple[float, float]:
    """The (m/s, rad/s) a command ran at: what it did over the simulated time it took."""
    if item.before is None or item.after is None:
        return 0.0, 0.0
    dt = item.after.sim_time_s - item.before.sim_time_s
    if dt <= 0:
        return 0.0, 0.0
    if isinstance(item.signal, Straight):
        return item.result.distance_mm / 1000.0 / dt, 0.0
    return 0.0, math.radians(item.result.angle_deg) / dt


def _twist(v: float, w: float) -> Any:
    return m.build("geometry_msgs/msg/Twist", linear=m.vector(v), angular=m.vector(0.0, 0.0, w))


def _step_messages(line: _Timeline, ns: int, seen: Seen, record: StepRecord | None) -> None:
    if seen.scan is not None:
        line.add("/scan", ns, laser_scan(seen.scan, ns))
    for name, image in seen.images.items():
        form = image.media_type.split("/")[-1]
        line.add(image_topic(name), ns, m.build("sensor_msgs/msg/CompressedImage", header=m.header(ns, "base_link"),
                                                format=form, data=np.frombuffer(image.data, dtype=np.uint8)))
    if record is None:
        return
    for attack in record.attacks:
        _log(line, line.next(), WARN, "attacker",
             f"step {record.step}: {attack.kind} injected through the {attack.channel}: {attack.payload}")
    _log(line, line.next(), INFO, "instruction", f"step {record.step}: {record.instruction}")
    for attempt in record.attempts:
        at = line.next()
        _log(line, at, INFO, "llm", f"step {record.step}, attempt {attempt.index + 1}: {attempt.raw_text}")
        control = [s.model_dump(mode="json") for s in attempt.response.control] if attempt.response else None
        _string(line, "/safeembodai/plan", at, {
            "step": record.step, "attempt": attempt.index + 1, "control": control, "accepted": attempt.accepted,
            "parse_error": attempt.parse_error,
            "verdicts": [v.model_dump(mode="json") for v in attempt.verdicts]})
        if attempt.accepted:
            _log(line, at, INFO, "guard", f"step {record.step}, attempt {attempt.index + 1} accepted")
        else:
            _log(line, at, WARN, "guard", f"step {record.step}, attempt {attempt.index + 1} refused: "
                 + "; ".join(attempt.failures()))
    if record.enforced is not None:  # on_exhausted: enforce: the rules' cut of the refused answer ran, or a hold
        at = line.next()
        enforced = record.enforced  # a plan message as the attempts' (guard-bag reads its control), marked enforced
        _string(line, "/safeembodai/plan", at, {
            "step": record.step, "attempt": None if enforced.attempt is None else enforced.attempt + 1,
            "control": [s.model_dump(mode="json") for s in enforced.plan], "accepted": enforced.ran,
            "parse_error": None, "verdicts": [v.model_dump(mode="json") for v in enforced.verdicts],
            "enforced": {"source": enforced.source, "ran": enforced.ran, "note": enforced.note}})
        _log(line, at, WARN, "guard", f"step {record.step}: {record.enforced.note}")


def trial_messages(spec: TrialSpec, records: list[StepRecord], result: TrialResult | None, capture: TrialCapture,
                   robot: RobotSpec, about: dict[str, Any] | None = None) -> list[tuple[str, int, Any]]:
    """The trial's messages (topic, log time in ns, message), in log-time order (module docstring)."""
    line = _Timeline()
    by_step = {record.step: record for record in records}
    start = line.at(0.0)
    _string(line, "/safeembodai/trial", start, {"trial": spec.model_dump(mode="json"), **(about or {}),
                                                 "robot": {"radius_mm": robot.radius_mm, "width_mm": robot.width_mm,
                                                           "length_mm": robot.length_mm}})
    collisions: list[Pose] = []
    world: WorldSnapshot | None = None
    pose: Pose | None = None
    now = 0.0
    for event in capture.events:
        if isinstance(event, Observed):
            now, world, pose = event.sim_time_s, event.world, event.pose or pose
            ns = line.at(now)
            line.add("/clock", ns, m.build("rosgraph_msgs/msg/Clock", clock=m.stamp(ns)))
            if pose is not None:
                _pose_messages(line, ns, pose)
            _markers(line, ns, world, pose, robot, collisions)
        elif isinstance(event, Seen):
            _step_messages(line, line.at(now), event, by_step.get(event.step))
        else:
            if event.before is not None:
                now = event.before.sim_time_s
            v, w = _velocity(event)
            line.add("/cmd_vel", line.at(now), _twist(v, w))
            _log(line, line.at(now), INFO, "robot", f"step {event.step}: executing {event.signal.describe()}")
            now = event.after.sim_time_s if event.after is not None else now
            ns = line.at(now)
            line.add("/cmd_vel", ns, _twist(0.0, 0.0))
            pose, world = event.pose_after or pose, event.after or world
            if event.result.collided and pose is not None:
                collisions.append(pose)
                _log(line, ns, ERROR, "world", f"step {event.step}: {event.result.collision or 'unattributed'} "
                     f"collision: {event.result.detail}")
            line.add("/clock", ns, m.build("rosgraph_msgs/msg/Clock", clock=m.stamp(ns)))
            if pose is not None:
                _pose_messages(line, ns, pose)
            _markers(line, ns, world, pose, robot, collisions)
    if result is not None:
        end = line.at(now)
        _log(line, end, INFO, "trial", f"{spec.trial_id}: {result.outcome.value}"
             + (f" ({result.detail})" if result.detail else ""))
        _string(line, "/safeembodai/trial", end, {"result": {
            "outcome": result.outcome.value, "detail": result.detail, "steps": result.steps,
            "collisions_self": result.collisions_self, "collisions_struck": result.collisions_struck,
            "collisions_struck_standing": result.collisions_struck_standing}})
    return line.messages


def write_bag(path: str | Path, items: Iterable[tuple[str, int, Any]], storage: str = "mcap", *,
              replace: bool = False) -> Path:
    """Write ``items`` (topic, log time in ns, a message made by :func:`~safeembodai_core.ros.messages.build`)
    as a rosbag2 folder at ``path``, all or nothing. ``path`` must not exist unless ``replace`` says a bag there
    may be replaced (by the new one, once it is whole)."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    if storage not in STORAGES:
        raise BagWriteError(f"unknown bag storage {storage!r}: use one of {', '.join(STORAGES)}")
    target = Path(path)
    if target.exists() and not replace:
        raise BagWriteError(f"{target} exists: choose a new --out (a bag is never written over)")
    store = m.typestore()
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        # written as <a fresh hidden folder>/<the final name>: rosbags names its storage file and
        # metadata.yaml after the bag's folder, so the bag reads the same once moved into place
        aside = Path(tempfile.mkdtemp(prefix=f".{target.name[:40]}.", suffix=".partial", dir=target.parent))
    except OSError as error:
        raise BagWriteError(f"cannot write the bag {target}: {error.strerror or error}") from None
    partial = aside / target.name
    try:
        plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
        with Writer(partial, version=8, storage_plugin=plugin) as writer:
            connections: dict[str, Any] = {}
            for topic, ns, message in items:
                typename = message.__msgtype__  # what rosbags built it as (messages.build)
                if topic not in connections:
                    connections[topic] = writer.add_connection(topic, typename, typestore=store)
                writer.write(connections[topic], ns, m.serialize(message, typename))
        if replace and target.is_dir() and not target.is_symlink():
            shutil.rmtree(target)
        os.replace(partial, target)
    except Exception as error:  # rosbags', struct's or the file system's: the bag is not written, nothing is left
        raise BagWriteError(f"cannot write the bag {target}: {type(error).__name__}: {error}") from None
    finally:
        shutil.rmtree(aside, ignore_errors=True)
    return target
