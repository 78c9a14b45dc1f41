"""An agent's tool call, read strictly before anything is forwarded: :func:`read_call`.

The arguments of a ``tools/call`` are outside bytes (``safeembodai_core/trust/inventory.py``): the agent wrote
them, and an injected instruction may have. :func:`read_call` reads them by the tool's kind in the
policy (ros-mcp 3.x's argument names) and answers what to do, or raises :class:`CallRefused` saying
why and how to amend:

* a publish to a velocity topic is a :class:`Motion` (its messages read as ``geometry_msgs`` Twist or
  TwistStamped, every field present, finite numbers only), for the guard to judge;
* anything else the policy allows is a :class:`Forward` of the arguments in their canonical form
  (names resolved, types in the policy's spelling), so what runs is what was read;
* the rest is refused: an unmapped tool, an unlisted topic, service, action or parameter, another
  robot than the configured one, an unknown or mistyped argument.

Names follow ROS (:mod:`~safeembodai_core.rosbridge.names`): ``cmd_vel`` is ``/cmd_vel``; ``/cmd_vel/``,
``//cmd_vel`` and ``~/cmd_vel`` are not names and are refused; ``/CMD_VEL`` and ``/robot1/cmd_vel`` are
other topics, refused unless the policy lists them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import SafeEmbodAIError
from ..trust.quoting import quote_untrusted
from ..ros.laser_scan import shown
from ..ros.twist import Twist
from ..rosbridge.messages import MessageError, conform
from ..rosbridge.names import RosNameError, normalize_type, resolve_name
from .policy import Policy

FULL_TWIST = '{"linear": {"x": 0.2, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}'
#: ros-mcp 3.x's arguments of each kind: (required, optional)
ARGUMENTS: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "publish_once": (("topic", "msg_type", "msg"), ()),
    "publish_for_durations": (("topic", "msg_type", "messages", "durations"), ("rate_hz",)),
    "call_service": (("service_name", "service_type", "request"), ("timeout",)),
    "send_action_goal": (("action_name", "action_type", "goal"), ("timeout",)),
    "cancel_action_goal": (("action_name", "goal_id"), ()),
    "set_parameter": (("name", "value"), ()),
    "delete_parameter": (("name",), ()),
    "connect_to_robot": ((), ("ip", "port", "ping_timeout", "port_timeout")),
    "ping_robots": ((), ("targets", "ping_timeout", "port_timeout")),
}


class CallRefused(SafeEmbodAIError, ValueError):
    """A call refused before the guard judged any motion: ``reason``, and ``advice`` to amend it."""

    def __init__(self, reason: str, advice: str = "") -> None:
        super().__init__(reason)
        self.reason, self.advice = reason, advice


@dataclass(frozen=True)
class Hold:
    """One message of a motion: the twist, held ``duration_s``, and the message forwarded for it."""

    twist: Twist
    duration_s: float
    message: dict[str, Any]


@dataclass(frozen=True)
class Motion:
    """A publish to a velocity topic: ``holds`` in order (``publish_once``: one, of duration 0)."""

    tool: str
    kind: str
    topic: str
    msg_type: str
    holds: tuple[Hold, ...]

    @property
    def is_stop(self) -> bool:
        return all(hold.twist == Twist(0.0, 0.0) for hold in self.holds)


@dataclass(frozen=True)
class Forward:
    """A call forwarded as it is read: ``arguments`` canonical; ``actuates`` unless read-only."""

    tool: str
    kind: str
    arguments: dict[str, Any]
    actuates: bool = True


def read_call(tool: str, arguments: Any, policy: Policy, robot: tuple[str, int], *,
              holonomic: bool = False) -> Motion | Forward:
    """What to do with ``tool(**arguments)`` under ``policy`` for the robot at ``robot`` (host, port)."""
    kind = policy.tools.get(tool) if isinstance(tool, str) else None
    if kind is None:
        raise CallRefused(f"tool {quote_untrusted(tool, 80)}: the policy maps no such tool, so it is refused",
                          "use the tools the policy maps (docs/guard_mcp.md)")
    if kind == "read_only":
        return Forward(tool, kind, dict(arguments or {}), actuates=False)
    args = _arguments(tool, kind, arguments)
    if kind in ("publish_once", "publish_for_durations"):
        return _publish(tool, kind, args, policy, holonomic)
    if kind == "call_service":
        name = _listed(args["service_name"], "service", policy.allow.services)
        return Forward(tool, kind, {"service_name": name, "service_type": _type(args["service_type"], "srv"),
                                    "request": _object(args["request"], "request"), **_timeout(args, "timeout")})
    if kind in ("send_action_goal", "cancel_action_goal"):
        name = _listed(args["action_name"], "action", policy.allow.actions)
        if kind == "cancel_action_goal":
            return Forward(tool, kind, {"action_name": name, "goal_id": _text(args["goal_id"], "goal_id")})
        return Forward(tool, kind, {"action_name": name, "action_type": _type(args["action_type"], "action"),
                                    "goal": _object(args["goal"], "goal"), **_timeout(args, "timeout")})
    if kind in ("set_parameter", "delete_parameter"):
        name = _text(args["name"], "name")
        if name not in policy.allow.parameters:
            raise CallRefused(f"parameter {quote_untrusted(name, 80)} is not in the policy's allow.parameters: "
                              f"{kind} refused")
        return Forward(tool, kind, {"name": name, **({"value": _text(args["value"], "value")}
                                                     if kind == "set_parameter" else {})})
    return _retarget(tool, kind, args, robot)


def _arguments(tool: str, kind: str, arguments: Any) -> dict[str, Any]:
    if arguments is None:
        arguments = {}
    if not isinstance(arguments, dict):
        raise CallRefused(f"{tool}: the arguments must be an object, not {shown(arguments)}")
    required, optional = ARGUMENTS[kind]
    unknown = sorted(str(key) for key in arguments if key not in required + optional)
    missing = [key for key in required if key not in arguments]
    if unknown or missing:
        raise CallRefused(f"{tool}: " + "; ".join(([f"unknown argument {quote_untrusted(', '.join(unknown), 80)}"]
                                                   if unknown else []) + ([f"no {', '.join(missing)}"] if missing
                                                                          else [])),
                          f"{tool} takes {', '.join(required + optional)}")
    return arguments


def _text(value: Any, what: str) -> str:
    if not isinstance(value, str) or not value or len(value) > 256:
        raise CallRefused(f"{what} must be text of 1 to 256 characters, not {shown(value)}")
    return value


def _object(value: Any, what: str) -> dict[str, Any]:
    if not isinstance(value, dict):
        raise CallRefused(f"{what} must be an object, not {shown(value)}")
    return value


def _number(value: Any, what: str, low: float, high: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise CallRefused(f"{what} must be a number, not {shown(value)}")
    try:
        number = float(value)
    except OverflowError:
        number = math.inf
    if not (math.isfinite(number) and low <= number <= high):
        raise CallRefused(f"{what} must be a finite number within [{low:g}, {high:g}], not {shown(value)}")
    return number


def _timeout(args: dict[str, Any], key: str) -> dict[str, float]:
    return {} if args.get(key) is None else {key: _number(args[key], key, 0.1, 60.0)}


def _name(value: Any, what: str) -> str:
    try:
        return resolve_name(value, what)
    except RosNameError as error:
        raise CallRefused(str(error), f"write the {what}'s full ROS name, such as /cmd_vel") from None


def _type(value: Any, kind: str) -> str:
    try:
        normalize_type(value, kind)
    except RosNameError as error:
        raise CallRefused(str(error)) from None
    return str(value)


def _listed(value: Any, what: str, allowed: list[str]) -> str:
    name = _name(value, what)
    if name not in allowed:
        raise CallRefused(f"{what} {name} is not in the policy's allowlist: refused (an unlisted {what} may actuate)")
    return name


def _publish(tool: str, kind: str, args: dict[str, Any], policy: Policy, holonomic: bool) -> Motion | Forward:
    topic, msg_type = _name(args["topic"], "topic"), args["msg_type"]
    many = kind == "publish_for_durations"
    messages = args["messages"] if many else [args["msg"]]
    if many:
        durations, rate = args["durations"], _number(args.get("rate_hz", 0), "rate_hz", 0.0, 100.0)
        if not isinstance(messages, list) or not isinstance(durations, list) or len(messages) != len(durations):
            raise CallRefused("messages and durations must be lists of the same length")
        if len(messages) > policy.max_messages:
            raise CallRefused(f"{len(messages)} messages: at most {policy.max_messages} are judged")
        seconds = [_number(d, f"durations[{k}]", 0.0, policy.max_motion_s) for k, d in enumerate(durations)]
        if sum(seconds) > policy.max_motion_s:
            raise CallRefused(f"the motion lasts {sum(seconds):g} s: at most {policy.max_motion_s:g} s is judged",
                              "split it into shorter calls")
    else:
        seconds, rate = [0.0], 0.0
    judged = policy.velocity_type(topic, msg_type) if isinstance(msg_type, str) else None
    if topic in policy.velocity_topics:
        if judged is None:
            raise CallRefused(f"{topic} is judged as {' or '.join(policy.velocity_topics[topic])}, not "
                              f"{quote_untrusted(msg_type, 80)}: refused")
        holds = tuple(_hold(m, d, normalize_type(judged), f"messages[{k}]" if many else "msg", holonomic)
                      for k, (m, d) in enumerate(zip(messages, seconds)))
        return Motion(tool, kind, topic, judged, holds)
    allowed = policy.allowed_type(topic, msg_type) if isinstance(msg_type, str) else None
    if topic not in policy.allow.topics or allowed is None:
        raise CallRefused(f"a publish to {topic} ({quote_untrusted(msg_type, 80)}) is not in the policy: refused "
                          "(an unlisted topic may actuate)", f"the judged velocity topics: "
                                                             f"{', '.join(policy.velocity_topics)}")
    for k, message in enumerate(messages):
        _object(message, f"messages[{k}]" if many else "msg")
    arguments: dict[str, Any] = {"topic": topic, "msg_type": allowed}
    arguments.update({"messages": messages, "durations": seconds, "rate_hz": rate} if many else {"msg": messages[0]})
    return Forward(tool, kind, arguments)


def _hold(message: Any, duration_s: float, msg_type: str, where: str, holonomic: bool) -> Hold:
    stamped = msg_type.endswith("TwistStamped")
    fields = ("header", "twist") if stamped else ("linear", "angular")
    if not isinstance(message, dict) or set(message) != set(fields):
        got = sorted(map(str, message)) if isinstance(message, dict) else shown(message)
        raise CallRefused(f"{where}: a {msg_type} has exactly the fields {', '.join(fields)}, got {got}",
                          f"write every field: {FULL_TWIST}" + (" inside twist, with a header" if stamped else ""))
    try:
        twist = Twist.from_ros(message, holonomic=holonomic)
        header = conform("std_msgs/msg/Header", message["header"], {"sec": 0, "nanosec": 0}) if stamped else None
    except (ValueError, TypeError, OverflowError, MessageError) as error:
        raise CallRefused(f"{where}: {error}", f"write every field as a finite number: {FULL_TWIST}") from None
    if header is not None and len(header["frame_id"]) > 256:
        raise CallRefused(f"{where}: header.frame_id is longer than 256 characters")
    body = {"linear": {"x": twist.linear_x, "y": twist.linear_y, "z": 0.0},
            "angular": {"x": 0.0, "y": 0.0, "z": twist.angular_z}}
    return Hold(twist, duration_s, {"header": message["header"], "twist": body} if stamped else body)


def _retarget(tool: str, kind: str, args: dict[str, Any], robot: tuple[str, int]) -> Forward:
    """connect_to_robot / ping_robots: only towards the configured robot (ros-mcp's defaults filled in)."""
    timeouts = {key: _number(args[key], key, 0.1, 10.0) for key in ("ping_timeout", "port_timeout") if key in args}
    if kind == "connect_to_robot":
        targets = [{"ip": args.get("ip") or "127.0.0.1", "port": args.get("port") or 9090}]
    else:
        targets = args.get("targets") or [{"ip": "127.0.0.1", "port": 9090}]
        if not isinstance(targets, list) or len(targets) > 16:
            raise CallRefused("targets must be a list of at most 16 {ip, port} objects")
    host, port = robot
    for target in targets:
        if not isinstance(target, dict) or set(target) != {"ip", "port"}:
            raise CallRefused(f"a target is an object of ip and port, not {shown(target)}")
        ip, number = target["ip"], target["port"]
        if isinstance(number, str) and number.strip().isdigit():
            number = int(number.strip())
        if not isinstance(ip, str) or ip.strip().lower() != host.lower() or number != port or isinstance(number, bool):
            raise CallRefused(f"{tool}: only the configured robot {host}:{port} may be reached, not "
                              f"{quote_untrusted(ip, 60)}:{quote_untrusted(number, 12)}",
                              "guard-mcp guards one robot; another needs its own guard-mcp")
    canonical = [{"ip": host, "port": port}] * len(targets)
    return Forward(tool, kind, ({"ip": host, "port": port} if kind == "connect_to_robot" else {"targets": canonical})
                   | timeouts, actuates=False)
