"""``geometry_msgs/Twist`` held for a while, as the contract's signals (issue 23, part 2).

A differential-drive robot driving ``linear.x`` (m/s) and turning ``angular.z`` (rad/s) for ``t``
seconds sweeps an arc, not a straight line and a turn. :func:`arc_signals` writes the arc as the
contract's signals -- short straights along the arc's chords, each between turns, the chords taken
at the middle heading of their piece (at most ``step_mm`` and ``step_deg`` per piece) -- so that
every rule judges the ground the body sweeps, piece by piece from where the earlier pieces leave
it, with the same code as an LLM's plan. :class:`Twist` reads a command strictly: only a planar
command (``linear.x``, ``angular.z``) can be judged; anything else, or a non-finite number, is an
error, never a guess.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Literal

from ..models import Straight, Turn
from .laser_scan import finite_number, shown

#: The longest straight and the largest turn of one piece of an arc.
STEP_MM = 50.0
STEP_DEG = 5.0
#: Most pieces one command is cut into (100 m, or 28 turns): a longer arc is not judged, but refused.
MAX_PIECES = 2000


def longest_judged_s(twist: "Twist", step_mm: float = STEP_MM, step_deg: float = STEP_DEG) -> float:
    """How long ``twist`` can be held before its arc needs more than :data:`MAX_PIECES` pieces (a
    billionth short of it: :func:`arc_signals` rounds its own way, and must cut this hold into no more)."""
    per_second = max(abs(twist.linear_x) * 1000.0 / step_mm, abs(math.degrees(twist.angular_z)) / step_deg)
    return math.inf if per_second == 0 else MAX_PIECES / per_second * (1.0 - 1e-9)


def piece_count(distance_mm: float, angle_deg: float, step_mm: float = STEP_MM, step_deg: float = STEP_DEG) -> int:
    """How many pieces an arc of ``distance_mm`` and ``angle_deg`` is cut into (at most ``step_mm``
    and ``step_deg`` each); ``ValueError`` for one too long to count."""
    if not (math.isfinite(distance_mm) and math.isfinite(angle_deg)):
        raise ValueError(f"an arc of {distance_mm!r} mm and {angle_deg!r} degrees cannot be cut into pieces")
    return max(1, math.ceil(abs(distance_mm) / step_mm), math.ceil(abs(angle_deg) / step_deg))


def _finite(name: str, value: Any) -> float:
    return finite_number("Twist", name, value)


def _only(message: Mapping[Any, Any], fields: tuple[str, ...], what: str) -> None:
    """Refuse a dict that lacks one of ``fields`` or has another key."""
    missing = [name for name in fields if name not in message]
    unknown = sorted(str(name) for name in message if name not in fields)
    if missing or unknown:
        problems = ([f"no {', '.join(missing)}"] if missing else []) + (
            [f"unknown field {', '.join(map(shown, unknown))}"] if unknown else [])
        raise ValueError(f"not a {what}: {'; '.join(problems)}")


def _json_parts(message: Mapping[Any, Any]) -> dict[str, Any]:
    """The six numbers of a ``Twist`` (or ``TwistStamped``) dict, named as ROS names them, unread."""
    if "twist" in message:
        _only(message, ("header", "twist"), "geometry_msgs/TwistStamped")
        if not isinstance(message["header"], Mapping):
            raise ValueError(f"TwistStamped.header must be an object, got {shown(message['header'])}")
        message = message["twist"]
        if not isinstance(message, Mapping):
            raise ValueError(f"TwistStamped.twist must be a geometry_msgs/Twist object, got {shown(message)}")
    _only(message, ("linear", "angular"), "geometry_msgs/Twist")
    parts = {}
    for vector in ("linear", "angular"):
        if not isinstance(message[vector], Mapping):
            raise ValueError(f"Twist.{vector} must be an object of x, y, z, got {shown(message[vector])}")
        _only(message[vector], ("x", "y", "z"), f"geometry_msgs/Vector3 (Twist.{vector})")
        parts.update({f"{vector}.{axis}": message[vector][axis] for axis in ("x", "y", "z")})
    return parts


@dataclass(frozen=True)
class Twist:
    """A planar velocity command: forward speed (m/s, negative backwards), turn rate (rad/s,
    counter-clockwise) and, for a holonomic base, sideways speed (m/s, positive to the left), as
    ``geometry_msgs/Twist``'s ``linear.x``, ``angular.z`` and ``linear.y``."""

    linear_x: float
    angular_z: float
    linear_y: float = 0.0

    def __post_init__(self) -> None:
        for name in ("linear_x", "angular_z", "linear_y"):
            object.__setattr__(self, name, _finite(name, getattr(self, name)))

    def scaled(self, factor: float) -> Twist:
        """The same path at ``factor`` times the speed (every part scaled: the curvature is kept)."""
        # + 0.0: a stop is 0.0, never -0.0
        return Twist(self.linear_x * factor + 0.0, self.angular_z * factor + 0.0, self.linear_y * factor + 0.0)

    @classmethod
    def from_ros(cls, message: Any, holonomic: bool = False) -> Twist:
        """A ``geometry_msgs/msg/Twist`` or ``TwistStamped``, decoded or as rosbridge sends it (module
        docstring). A command with vertical or roll/pitch parts, or sideways without ``holonomic``, is
        not the base's: refused, not dropped."""
        wire = isinstance(message, Mapping)
        if wire:
            parts = _json_parts(message)
        else:
            message = getattr(message, "twist", message)
            try:
                linear, angular = message.linear, message.angular
                parts = {"linear.x": linear.x, "linear.y": linear.y, "linear.z": linear.z,
                         "angular.x": angular.x, "angular.y": angular.y, "angular.z": angular.z}
            except AttributeError:
                raise ValueError(f"not a geometry_msgs/Twist: {type(message).__name__} has no linear/angular "
                                 "x, y, z") from None
        parts = {name: finite_number("Twist", name, value) for name, value in parts.items()}  # named as ROS names them
        for name in ("linear.y", "linear.z", "angular.x", "angular.y"):
            if parts[name] != 0.0 and not (holonomic and name == "linear.y"):
                sideways = " (a holonomic base: RobotSpec(holonomic=True))" if name == "linear.y" else ""
                raise ValueError(f"Twist {name} = {parts[name]!r}: only a planar command (linear.x, "
                                 f"angular.z{sideways}) can be judged")
        return cls(parts["linear.x"], parts["angular.z"], parts["linear.y"])


def arc_signals(twist: Twist, duration_s: float, step_mm: float = STEP_MM,
                step_deg: float = STEP_DEG) -> list[Straight | Turn]:
    """The arc ``twist`` sweeps in ``duration_s`` seconds as straights and turns (module docstring);
    empty for a zero command or duration."""
    duration_s = float(duration_s)
    if not math.isfinite(duration_s) or duration_s < 0:
        raise ValueError(f"duration_s must be a finite number of seconds >= 0, got {duration_s!r}")
    if twist.linear_y != 0.0:
        raise ValueError(f"Twist linear_y = {twist.linear_y!r}: a sideways command has no straights and turns; "
                         "only rules that judge the held motion (swept_body) can judge it")
    distance = abs(twist.linear_x) * 1000.0 * duration_s
    angle = math.degrees(twist.angular_z * duration_s)
    pieces = piece_count(distance, angle, step_mm, step_deg)
    if pieces > MAX_PIECES:
        raise ValueError(f"the arc of {distance:.0f} mm and {abs(angle):.0f} degrees needs {pieces} pieces, more than "
                         f"{MAX_PIECES}: judge a shorter hold (longest_judged_s)")
    direction: Literal["forward", "backward"] = "forward" if twist.linear_x >= 0 else "backward"
    side: Literal["left", "right"] = "left" if angle >= 0 else "right"

    def turn(degrees: float) -> list[Straight | Turn]:
        return [Turn(command="turn", direction=side, angle=abs(degrees))] if abs(degrees) > 1e-9 else []

    def straight(millimetres: float) -> list[Straight | Turn]:
        return [Straight(command="straight", direction=direction, distance=millimetres)] if millimetres > 1e-9 else []

    signals: list[Straight | Turn] = turn(angle / pieces / 2)
    for piece in range(pieces):
        signals += straight(distance / pieces)
        signals += turn(angle / pieces if piece < pieces - 1 else angle / pieces / 2)
    return signals
