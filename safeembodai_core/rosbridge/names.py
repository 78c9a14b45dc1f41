"""ROS names on the wire: topic and service names, message and service type names.

A name is resolved once, where it enters, so that ``cmd_vel`` and ``/cmd_vel`` are one topic (ROS 2
resolves a relative name against the node's namespace, here the root) and a variant that ROS would
refuse (``/cmd_vel/``, ``//cmd_vel``, ``~/cmd_vel``, a space) is refused rather than left to match
nothing. Names are case-sensitive, as in ROS: ``/CMD_VEL`` is another topic.

Types are written ``pkg/msg/Type`` (ROS 2); the ROS 1 spelling ``pkg/Type`` names the same type and
is rewritten to it, so a client may use either.
"""

from __future__ import annotations

import re

from ..trust.quoting import quote_untrusted

#: the longest topic, service or type name read from a client
MAX_NAME_CHARS = 256
_TOKEN = r"[A-Za-z_][A-Za-z0-9_]*"
_NAME = re.compile(rf"/?{_TOKEN}(?:/{_TOKEN})*")
_TYPE = re.compile(rf"({_TOKEN})/(?:(msg|srv|action)/)?({_TOKEN})")


class RosNameError(ValueError):
    """A topic, service or type name that ROS would not accept; the message says which and why."""


def resolve_name(name: object, what: str = "topic") -> str:
    """``name`` as an absolute ROS name (``cmd_vel`` -> ``/cmd_vel``), or :class:`RosNameError`."""
    if not isinstance(name, str):
        raise RosNameError(f"{what} name must be a string, not {type(name).__name__}")
    if len(name) > MAX_NAME_CHARS or not _NAME.fullmatch(name):
        raise RosNameError(f"{what} name {quote_untrusted(name, 60)} is not a valid ROS name "
                         "(letters, digits and _ in /-separated tokens, no trailing /)")
    return name if name.startswith("/") else "/" + name


def normalize_type(name: object, kind: str = "msg") -> str:
    """``name`` as ``pkg/<kind>/Type``: ``sensor_msgs/LaserScan`` -> ``sensor_msgs/msg/LaserScan``."""
    if not isinstance(name, str):
        raise RosNameError(f"a type must be a string, not {type(name).__name__}")
    match = _TYPE.fullmatch(name) if len(name) <= MAX_NAME_CHARS else None
    if match is None or (match.group(2) or kind) != kind:
        raise RosNameError(f"type {quote_untrusted(name, 60)} is not a ROS {kind} type "
                         f"(pkg/{kind}/Type, or pkg/Type)")
    return f"{match.group(1)}/{kind}/{match.group(3)}"
