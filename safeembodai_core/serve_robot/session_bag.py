"""A served room's session as a ROS 2 bag (rosbag2: MCAP by default, or SQLite), written as it goes.

What the room served and what it was told, on the room's clock (seconds since the session began, as
the messages' header stamps say; each event at least 1 ns after the one before, in the order they
happened; an ``/odom``'s TF, pose and clock share its time):

* ``/scan``, ``/odom``, ``/camera/image_raw/compressed``, ``/safeembodai/events`` -- every message the
  room published, at the rate it was served, whether or not a client subscribed (a ``null`` range on
  rosbridge's wire is ``+inf`` here: no return within range, as the room means it);
* ``/tf`` (``odom`` -> ``base_link``), ``/pose`` (``geometry_msgs/PoseStamped``, for ``safeembodai
  guard-bag --pose /pose``) and ``/clock`` -- with each ``/odom``;
* ``/cmd_vel`` (``geometry_msgs/Twist``) -- every command the room took, when it took it (a
  ``TwistStamped`` as its twist); one it could not read is a ``/rosout`` warning with the reason;
* ``/safeembodai/trial`` (``std_msgs/String``, JSON) -- the trial's id and seed, the robot and the rates
  at the start; the result when an outcome is reached (the session may go on serving after it).

Messages go to the storage as they come (MCAP: 1 MiB chunks; SQLite: one transaction), so a long
session holds no more than a chunk in memory. The bag is written in a hidden scratch folder beside
its place (``bags/<trial>`` of the run folder, where ``ablate --bags`` puts a trial's) and renamed into
place by :meth:`SessionBag.close`. A bag that cannot be written (a full disk) is given up, logged and
its scratch removed: the robot is served on and the run folder's record is kept.
"""

from __future__ import annotations

import base64
import json
import math
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import structlog

from ..errors import SafeEmbodAIError
from ..models import TrialResult
from ..ros.twist import Twist
from ..trust.text import terminal_text
from . import messages as wire

log = structlog.get_logger(__name__)

#: Every topic a session's bag holds: topic -> type.
TOPICS = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/pose": "geometry_msgs/msg/PoseStamped",
    "/odom": wire.ODOMETRY,
    "/scan": wire.LASER_SCAN,
    "/camera/image_raw/compressed": wire.COMPRESSED_IMAGE,
    "/cmd_vel": wire.TWIST,
    "/safeembodai/events": wire.STRING,
    "/safeembodai/trial": wire.STRING,
    "/rosout": "rcl_interfaces/msg/Log",
}
STORAGES = ("mcap", "sqlite3")
_SUFFIXES = {".mcap": "mcap", ".db3": "sqlite3"}
INFO, WARN = 20, 30


class Command(Protocol):
    """A command as the room took it (:class:`~.served_room.Received`): its twist, None when it could
    not be read (``error`` says why)."""

    @property
    def twist(self) -> Twist | None: ...
    @property
    def topic(self) -> str: ...
    @property
    def type(self) -> str: ...
    @property
    def client(self) -> str: ...
    @property
    def error(self) -> str: ...


def from_wire(typename: str, value: Any) -> Any:
    """A message as rosbridge's JSON writes it (``uint8[]`` in base64, ``null`` for a non-finite
    float) as ``rosbags`` builds it; fields it lacks take their ROS defaults, unknown keys are dropped."""
    from ..ros import messages as m

    fields = m.typestore().fielddefs[typename][1]
    given = value if isinstance(value, dict) else {}
    return m.build(typename, **{name: _field(node, given[name]) for name, node in fields if name in given})


def _field(node: tuple[Any, Any], value: Any) -> Any:
    kind, detail = node
    name = getattr(kind, "name", str(kind))
    if name == "NAME":
        return from_wire(detail, value)
    if name == "BASE":
        return _number(detail[0], value)
    inner = detail[0]
    if getattr(inner[0], "name", "") == "NAME":
        return [from_wire(inner[1], item) for item in value or []]
    base = inner[1][0]
    if base in ("uint8", "char", "byte") and isinstance(value, str):
        return np.frombuffer(base64.b64decode(value), dtype=np.uint8)
    return [_number(base, item) for item in value or []]


def _number(base: str, value: Any) -> Any:
    if base == "string":
        return str(value)
    if base == "bool":
        return bool(value)
    if base.startswith("float"):
        return math.inf if value is None else float(value)
    return int(value)


class SessionBag:
    """One session's bag, open from the session's start to :meth:`close` (module docstring); used
    from one thread, the one that made it (SQLite's rule: ``Session.serve`` makes, feeds and closes it
    in its own)."""

    def __init__(self, target: str | Path, storage: str = "mcap") -> None:
        from rosbags.rosbag2 import StoragePlugin, Writer

        if storage not in STORAGES:
            raise SafeEmbodAIError(f"unknown bag storage {storage!r}: use one of {', '.join(STORAGES)}")
        self.target, self.storage = Path(target), storage
        self.path: Path | None = None  # where the bag is once closed whole
        self.error = ""  # why the bag was given up
        self._last = -1
        self._connections: dict[str, Any] = {}
        self._writer: Any = None
        self._aside: Path | None = None
        if self.target.exists():
            raise SafeEmbodAIError(f"{self.target} exists: a session's bag is never written over")
        try:
            self.target.parent.mkdir(parents=True, exist_ok=True)
            # rosbags names its files after the bag's folder: written as <scratch>/<final name>
            self._aside = Path(tempfile.mkdtemp(prefix=f".{self.target.name[:40]}.", suffix=".partial",
                                                dir=self.target.parent))
            plugin = StoragePlugin.MCAP if storage == "mcap" else StoragePlugin.SQLITE3
            writer = Writer(self._aside / self.target.name, version=8, storage_plugin=plugin)
            writer.open()
            self._writer = writer
        except Exception as error:
            if self._aside is not None:
                shutil.rmtree(self._aside, ignore_errors=True)
            raise SafeEmbodAIError(f"cannot write the session's bag {self.target}: {type(error).__name__}: "
                                   f"{error}") from None

    # -- what the session tells it ---------------------------------------------------------------

    def started(self, about: dict[str, Any]) -> None:
        """``/safeembodai/trial`` at the session's start: the trial, the robot, the rates (``about``)."""
        self._string("/safeembodai/trial", self._at(0.0), about)

    def published(self, topic: str, message: dict[str, Any], time_s: float) -> None:
        """A message the room published at ``time_s``, as rosbridge's JSON; ``/odom`` with its TF,
        pose and clock. A topic the bag does not know is left out."""
        from ..ros import messages as m

        typename = TOPICS.get(topic)
        if typename is None or self._writer is None:
            return
        ns = self._at(time_s)
        try:
            built = from_wire(typename, message)
            if topic == "/odom":
                pose = built.pose.pose
                stamped = m.build("geometry_msgs/msg/TransformStamped", header=built.header,
                                  child_frame_id=built.child_frame_id,
                                  transform=m.build("geometry_msgs/msg/Transform", translation=m.vector(
                                      pose.position.x, pose.position.y, pose.position.z), rotation=pose.orientation))
                self._write("/clock", ns, m.build("rosgraph_msgs/msg/Clock", clock=built.header.stamp))
                self._write("/tf", ns, m.build("tf2_msgs/msg/TFMessage", transforms=[stamped]))
                self._write("/pose", ns, m.build("geometry_msgs/msg/PoseStamped", header=built.header, pose=pose))
            self._write(topic, ns, built)
        except Exception as error:  # the bag's failure never ends the robot's session
            self._give_up(error)

    def received(self, received: Command, time_s: float) -> None:
        """A command the room took at ``time_s``: ``/cmd_vel``, or a ``/rosout`` warning when unreadable."""
        from ..ros import messages as m

        ns = self._at(time_s)
        if received.twist is None:
            self._log(ns, WARN, "serve_robot", f"{received.topic} ({received.type}) from {received.client}: not "
                                                f"read, the robot stops: {received.error}")
            return
        twist = received.twist
        self._write_safely("/cmd_vel", ns, m.build(wire.TWIST, linear=m.vector(twist.linear_x, twist.linear_y),
                                                   angular=m.vector(0.0, 0.0, twist.angular_z)))

    def ended(self, result: TrialResult, time_s: float) -> None:
        """The trial's result at the moment it was decided (``/rosout`` and ``/safeembodai/trial``)."""
        ns = self._at(time_s)
        self._log(ns, INFO, "trial", f"{result.spec.trial_id}: {result.outcome.value}"
                  + (f" ({result.detail})" if result.detail else ""))
        self._string("/safeembodai/trial", ns, {"result": {
            "outcome": result.outcome.value, "detail": result.detail, "steps": result.steps,
            "distance_mm": result.distance_mm, "collisions_self": result.collisions_self,
            "collisions_struck": result.collisions_struck,
            "collisions_struck_standing": result.collisions_struck_standing}})

    def close(self) -> Path | None:
        """Finish the bag and rename it into place (once); its path, or None when it was given up."""
        writer, self._writer = self._writer, None
        if writer is not None and self._aside is not None:
            try:
                writer.close()
                os.replace(self._aside / self.target.name, self.target)
                self.path = self.target
            except Exception as error:
                self._give_up(error)
            finally:
                shutil.rmtree(self._aside, ignore_errors=True)
        return self.path

    # -- writing ---------------------------------------------------------------------------------

    def _at(self, time_s: float) -> int:
        self._last = max(int(round(max(0.0, time_s) * 1e9)), self._last + 1)
        return self._last

    def _string(self, topic: str, ns: int, payload: dict[str, Any]) -> None:
        from ..ros import messages as m

        self._write_safely(topic, ns, m.build(wire.STRING, data=json.dumps(payload, ensure_ascii=True)))

    def _log(self, ns: int, level: int, name: str, text: str) -> None:
        from ..ros import messages as m

        self._write_safely("/rosout", ns, m.build("rcl_interfaces/msg/Log", stamp=m.stamp(ns), level=level, name=name,
                                                  msg=terminal_text(text, keep_layout=True), file="safeembodai",
                                                  function=name))

    def _write_safely(self, topic: str, ns: int, message: Any) -> None:
        try:
            self._write(topic, ns, message)
        except Exception as error:
            self._give_up(error)

    def _write(self, topic: str, ns: int, message: Any) -> None:
        from ..ros import messages as m

        if self._writer is None:
            return
        typename = TOPICS[topic]
        connection = self._connections.get(topic)
        if connection is None:
            connection = self._connections[topic] = self._writer.add_connection(topic, typename,
                                                                                typestore=m.typestore())
        self._writer.write(connection, ns, m.serialize(message, typename))

    def _give_up(self, error: BaseException) -> None:
        if self.error:
            return
        self.error = f"{type(error).__name__}: {error}"
        log.error("serve_robot.bag_failed", bag=str(self.target), error=self.error)
        writer, self._writer = self._writer, None
        if writer is not None:
            try:
                writer.close()
            except Exception:
                pass
        if self._aside is not None:
            shutil.rmtree(self._aside, ignore_errors=True)


def recorded_storage(folder: Path) -> str | None:
    """The storage of the rosbag2 folder at ``folder`` (``mcap`` or ``sqlite3``), None when it holds none."""
    if not folder.is_dir() or folder.is_symlink():
        return None
    for path in folder.iterdir():
        if path.suffix in _SUFFIXES and path.is_file():
            return _SUFFIXES[path.suffix]
    return None


def copy_bag(source: Path, target: str | Path, storage: str) -> Path:
    """The recorded bag at ``source`` written again at ``target`` in ``storage``, message by message
    (each read back whole: a damaged bag is an error naming it), all or nothing."""
    from rosbags.rosbag2 import Reader

    from ..ros import messages as m
    from ..ros.bag_export import write_bag

    store = m.typestore()
    try:
        reader = Reader(source)
        reader.open()
    except Exception as error:
        raise SafeEmbodAIError(f"cannot read the session's bag {source}: {type(error).__name__}: {error}") from None
    try:
        items = ((c.topic, ns, store.deserialize_cdr(raw, c.msgtype)) for c, ns, raw in reader.messages())
        return write_bag(target, items, storage)
    finally:
        reader.close()


def export_session_bag(run_dir: str | Path, trial_id: str, target: str | Path, storage: str) -> Path:
    """A session's recorded bag as ``storage`` at ``target`` (``safeembodai export`` of a session's
    run folder). A session cannot be replayed: its commands came over the wire, so its bag is the only
    record of what the room served; raises :class:`SafeEmbodAIError` saying why when there is none."""
    from ..runs.trial_files import ArtefactSettings, bag_file

    source = bag_file(run_dir, trial_id)
    if recorded_storage(source) is not None:
        return copy_bag(source, target, storage)
    why = (f"{run_dir} is a serve-robot session: its commands came over the wire, not from answers recorded here, "
           "so it cannot be replayed into a bag; its own bag is its record")
    if ArtefactSettings.recorded(run_dir).bag_storage is None:
        raise SafeEmbodAIError(f"{why}, and it was served with --bag none: there is nothing to export "
                               "(serve-robot records one unless told --bag none)")
    raise SafeEmbodAIError(f"{why}, and {source} is missing: the session did not end cleanly (serve-robot was "
                           f"killed before it closed the bag; an unfinished one may lie in a hidden .partial folder of "
                           f"{source.parent})")
