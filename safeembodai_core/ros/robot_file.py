"""The robot file: what a guard on the wire must know of the robot it guards, in one YAML file.

``safeembodai guard-node --robot ROBOT.yaml`` and ``guard-mcp --policy`` read it. It says the body
(``radius_mm`` or a polygon ``footprint_mm``, as :class:`~safeembodai_core.contracts.robot.RobotSpec` takes
them), whether the base drives sideways (``holonomic``), each scan source by its topic with the
scanner's mount and how its ``null`` ranges are read (:data:`~.laser_scan.NullRange`), the limits of
a velocity smoother under Nav2's names and units, and how long a command is held without a newer one
(``cmd_vel_timeout_s``). ``docs/robot_file.md`` lists the keys with their defaults and sources.

The file is outside bytes (``safeembodai_core/trust/inventory.py``): read by the bounded reader of files from
elsewhere (a regular file, at most :data:`MAX_BYTES`, UTF-8; a symlink given is followed once, here,
and the file it names read without following another), composed within a scenario's YAML limits,
with duplicate keys refused, and validated strictly: an unknown key, a missing body, a bool or text
where a number belongs, a non-finite number is a :class:`RobotFileError` naming the file, the line
and the key.
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictFloat, StringConstraints, ValidationError, \
    ValidationInfo, field_validator, model_validator

from ..errors import SafeEmbodAIError
from ..geometry import read_polygon
from ..contracts.robot import RobotSpec
from ..runs.files import read_run_text
from ..scenario.limits import BoundedLoader, yaml_error
from ..scenario.loader import _check_duplicate_keys, _did_you_mean, _line_of
from .laser_scan import NullRange, SensorMount, shown

#: The largest robot file read: a footprint of thousands of vertices fits many times over.
MAX_BYTES = 256 * 1024
#: A fully qualified ROS topic name (``/scan``, ``/front/scan``), as ``--scan`` names it.
TOPIC = r"^(/[A-Za-z_][A-Za-z0-9_]*)+$"

Number = Annotated[StrictFloat, Field(allow_inf_nan=False)]
#: Nav2 velocity_smoother's [x, y, theta]: m/s, m/s and rad/s (velocities), per second (accelerations).
Axes = tuple[Number, Number, Number]
#: The largest speed (m/s or rad/s) and acceleration (per second) a robot file may give: beyond any mobile
#: base, and what bounds the cost of judging the fastest command a guard may let through.
MAX_SPEED = 50.0
MAX_ACCELERATION = 1000.0


class RobotFileError(SafeEmbodAIError, ValueError):
    """A robot file that cannot be read or is not valid; the message names the file, line and key."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Mount(_Strict):
    """The scanner's origin in the robot frame (mm, x forward, y left) and its yaw (degrees,
    counter-clockwise from the heading): the static TF ``base_link`` -> the scan's ``frame_id``."""

    x_mm: Number = 0.0
    y_mm: Number = 0.0
    yaw_deg: Number = 0.0


class ScanSource(_Strict):
    """One ``sensor_msgs/LaserScan`` topic: its scanner's mount, and how its ``null`` ranges are read."""

    null_range: NullRange = "unknown"
    mount: Mount = Mount()


def _bounded(axes: tuple[float, float, float], name: str | None) -> tuple[float, float, float]:
    most = MAX_SPEED if name in ("max_velocity", "min_velocity") else MAX_ACCELERATION
    if any(abs(value) > most for value in axes):
        raise ValueError(f"must be within +-{most:g} on every axis, got {list(axes)}")
    return axes


class VelocitySmoother(_Strict):
    """Nav2 velocity_smoother's kinematic limits, under its names, its units and its defaults
    (``nav2_velocity_smoother/src/velocity_smoother.cpp``): each [x, y, theta]; decelerations are
    negative, as Nav2 writes them."""

    max_velocity: Axes = (0.5, 0.0, 2.5)
    min_velocity: Axes = (-0.5, 0.0, -2.5)
    max_accel: Axes = (2.5, 0.0, 3.2)
    max_decel: Axes = (-2.5, 0.0, -3.2)

    @field_validator("max_velocity", "max_accel")
    @classmethod
    def _not_negative(cls, axes: tuple[float, float, float], info: ValidationInfo) -> tuple[float, float, float]:
        if any(value < 0 for value in axes):
            raise ValueError(f"must be >= 0 on every axis (Nav2's convention), got {list(axes)}")
        return _bounded(axes, info.field_name)

    @field_validator("min_velocity", "max_decel")
    @classmethod
    def _not_positive(cls, axes: tuple[float, float, float], info: ValidationInfo) -> tuple[float, float, float]:
        if any(value > 0 for value in axes):
            raise ValueError(f"must be <= 0 on every axis (Nav2's convention), got {list(axes)}")
        return _bounded(axes, info.field_name)


class RobotFile(_Strict):
    """A robot file, validated (module docstring). Exactly one of ``radius_mm`` and ``footprint_mm``."""

    radius_mm: Annotated[Number, Field(gt=0, le=100_000)] | None = None
    footprint_mm: list[tuple[Number, Number]] | None = None
    holonomic: StrictBool = False
    scans: dict[Annotated[str, StringConstraints(pattern=TOPIC)], ScanSource] = Field(
        default_factory=lambda: {"/scan": ScanSource()}, min_length=1)
    velocity_smoother: VelocitySmoother = VelocitySmoother()
    cmd_vel_timeout_s: Annotated[Number, Field(gt=0)] = 0.5

    @field_validator("footprint_mm")
    @classmethod
    def _simple_polygon(cls, footprint: list[tuple[float, float]] | None) -> list[tuple[float, float]] | None:
        if footprint is not None:
            read_polygon(footprint)
        return footprint

    @model_validator(mode="after")
    def _one_body(self) -> RobotFile:
        if (self.radius_mm is None) == (self.footprint_mm is None):
            raise ValueError("give the body as radius_mm or as footprint_mm (a polygon), exactly one of them")
        return self

    def robot_spec(self) -> RobotSpec:
        """The body as the guard takes it: a disc of ``radius_mm``, or the footprint, whose radius is
        its farthest vertex from the centre and its width and length its extent along y and x."""
        if self.footprint_mm is None:
            assert self.radius_mm is not None  # _one_body
            return RobotSpec(radius_mm=self.radius_mm, width_mm=2 * self.radius_mm, length_mm=2 * self.radius_mm,
                             holonomic=self.holonomic)
        xs, ys = [x for x, _ in self.footprint_mm], [y for _, y in self.footprint_mm]
        reach = max((x * x + y * y) ** 0.5 for x, y in self.footprint_mm)
        return RobotSpec(radius_mm=reach, width_mm=max(ys) - min(ys), length_mm=max(xs) - min(xs),
                         footprint_mm=tuple(self.footprint_mm), holonomic=self.holonomic)

    @property
    def scan_topic(self) -> str:
        """The scan source listed first: the one a guard reads unless told another."""
        return next(iter(self.scans))

    def source(self, topic: str | None = None) -> ScanSource:
        """The scan source of ``topic`` (default :attr:`scan_topic`); a topic the file does not list is
        an error, never a guess at its scanner's place."""
        topic = self.scan_topic if topic is None else topic
        if topic not in self.scans:
            raise RobotFileError(f"the robot file lists no scan source {topic!r} (it lists {', '.join(self.scans)})")
        return self.scans[topic]

    def mount(self, topic: str | None = None) -> SensorMount:
        """Where the scanner of ``topic`` (default :attr:`scan_topic`) sits on the robot."""
        mount = self.source(topic).mount
        return SensorMount(x_mm=mount.x_mm, y_mm=mount.y_mm, yaw_deg=mount.yaw_deg)

    def null_range(self, topic: str | None = None) -> NullRange:
        """How a ``null`` range on ``topic`` (default :attr:`scan_topic`) is read, for
        ``LaserScan.from_ros(message, null_range=...)``."""
        return self.source(topic).null_range


def parse_robot_file(text: str, source: str = "<robot file>") -> RobotFile:
    """Validate robot file ``text``; every problem at once, each naming ``source``, the line and the key."""
    return parse_yaml_model(text, source, RobotFile, RobotFileError, "robot file",
                            "a scan source's topic must be a full ROS name, such as /scan")


Model = TypeVar("Model", bound=BaseModel)


def parse_yaml_model(text: str, source: str, model: type[Model], error: type[SafeEmbodAIError], what: str,
                     key_message: str = "a key here must be a full ROS name") -> Model:
    """``text`` read as YAML within a scenario's limits, duplicate keys refused, validated by ``model``:
    every problem at once as one ``error``, each naming ``source``, the line and the key (``what`` names
    the file's kind; ``key_message`` says what a refused mapping key must be). The robot file's reader,
    and any other strict YAML file of the wire's commands (guard-mcp's policy)."""
    loader = None
    try:
        loader = BoundedLoader(text, source)
        root = loader.get_single_node()
        _check_duplicate_keys(root, source)
        data = loader.construct_document(root) if root is not None else {}
    except yaml.YAMLError as failure:
        raise error(str(yaml_error(failure, source, text))) from None
    except SafeEmbodAIError as failure:  # a limit or a duplicate key
        raise error(str(failure)) from None
    finally:
        if loader is not None:
            loader.dispose()
    if not isinstance(data, dict):
        raise error(f"{source}: a {what} must be a YAML mapping, got {type(data).__name__}")
    try:
        return model.model_validate(data)
    except ValidationError as failure:
        problems = [_problem(item, root, source, model, key_message) for item in failure.errors()]
        raise error(f"invalid {what} {source}:\n  " + "\n  ".join(problems)) from None


def _problem(item: Any, root: yaml.Node | None, source: str, model: type[BaseModel], key_message: str) -> str:
    """``file:line: key: what is wrong, got what``, for one of pydantic's errors."""
    loc: tuple[Any, ...] = tuple(item["loc"])
    message = item["msg"]
    if loc and loc[-1] == "[key]":  # a mapping's key: a topic's name
        loc, message = loc[:-1], key_message
    if item["type"] == "extra_forbidden":
        message += _did_you_mean(model, loc)
    elif item["type"] != "missing" and not isinstance(item["input"], (dict, list)):
        message += f", got {shown(item['input'])}"
    line = _line_of(root, loc)
    where = f"{source}:{line}" if line else source
    return f"{where}: {'.'.join(map(str, loc)) or '(top level)'}: {message}"


def read_yaml_text(path: str | Path, error: type[SafeEmbodAIError], what: str) -> str:
    """The text of the YAML file ``path`` given to a command (a robot file, a guard-mcp policy): a symlink
    given is followed once, then the bounded reader (a regular file, at most :data:`MAX_BYTES`, UTF-8);
    a missing or unreadable file is one ``error`` naming it and ``what`` it is."""
    try:
        return read_run_text(Path(path).resolve(strict=True), MAX_BYTES)
    except FileNotFoundError:
        raise error(f"{path}: no such {what}") from None
    except (OSError, RuntimeError, SafeEmbodAIError) as failure:  # RuntimeError: a symlink loop (Python 3.11)
        raise error(f"{path}: cannot read the {what}: {failure}") from None


def read_robot_file(path: str | Path) -> RobotFile:
    """Read and validate the robot file at ``path`` (module docstring)."""
    return parse_robot_file(read_yaml_text(path, RobotFileError, "robot file"), str(path))
