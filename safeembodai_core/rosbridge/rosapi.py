"""The rosapi services, answered by the server from what it knows of its own small ROS graph.

A rosbridge client asks a robot what it has through the ``rosapi`` node's services: roslibpy's
``Ros.get_topics`` and friends, ros-mcp's read-only tools and its ROS-version probe. There is no
ROS graph behind this server, so it answers them itself, with the ROS 2 service types
(``rosapi_msgs/srv/Topics``, ...) and the field names of rosapi 2.x. The graph has two nodes: the
server's own (it publishes what it offers and what clients advertise, subscribes to what it accepts
and to what clients subscribe to, and provides the services added to it) and ``/rosapi``.

Where this server knows less than a ROS graph it answers as rosapi does for what does not exist: the
parameter services as for an empty parameter server, the service request and response details with
no typedefs, the action servers with none. ``get_time`` gives ``secs``/``nsecs`` beside ROS 2's
``sec``/``nanosec``: roslibpy 2.1's ``Ros.get_time`` reads the ROS 1 names.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from typing import Any, Callable

from ..trust.quoting import quote_untrusted
from .frames import FrameError, read_json
from .messages import time_of, typedefs
from .names import RosNameError, normalize_type, resolve_name

ROSAPI_NODE = "/rosapi"
MAX_DEFAULT_CHARS = 4096


@dataclass(frozen=True)
class Graph:
    """What the server knows when a rosapi service is called.

    :param topics: every topic's name and type (a topic accepted with several types: the first).
    :param published: topics the server node publishes (offered, or advertised by a client).
    :param subscribed: topics it subscribes to (accepted, or subscribed to by a client).
    :param services: every service's name and type, rosapi's included.
    """

    node: str
    distro: str
    now: float
    topics: dict[str, str]
    published: frozenset[str]
    subscribed: frozenset[str]
    services: dict[str, str]


def _text(args: dict[str, Any], key: str) -> str:
    value = args.get(key, "")
    if not isinstance(value, str):
        raise ValueError(f"the field {key!r} must be text, not {type(value).__name__}")
    return value


def _name(args: dict[str, Any], key: str) -> str:
    text = _text(args, key)
    try:
        return resolve_name(text, key) if text else ""
    except RosNameError as error:
        raise ValueError(str(error)) from None


def _type(args: dict[str, Any], kind: str) -> str:
    text = _text(args, "type")
    try:
        return normalize_type(text, kind) if text else ""
    except RosNameError as error:
        raise ValueError(str(error)) from None


def _provider(graph: Graph, service: str) -> str:
    if service not in graph.services:
        return ""
    return ROSAPI_NODE if service.startswith(ROSAPI_NODE + "/") else graph.node


def _node_details(graph: Graph, args: dict[str, Any]) -> dict[str, Any]:
    node = _name(args, "node")
    mine = sorted(name for name in graph.services if _provider(graph, name) == node)
    if node == graph.node:
        return {"subscribing": sorted(graph.subscribed), "publishing": sorted(graph.published), "services": mine}
    return {"subscribing": [], "publishing": [], "services": mine}


def _param(graph: Graph, args: dict[str, Any]) -> dict[str, Any]:
    """No parameter exists: rosapi answers the default, as JSON (a default that is not JSON as text)."""
    default = _text(args, "default_value")
    try:
        value = read_json(default, MAX_DEFAULT_CHARS) if default else ""
    except FrameError:
        value = default
    return {"value": json.dumps(value)}


def _service_details(graph: Graph, args: dict[str, Any]) -> dict[str, Any]:
    """No service definitions are known here: rosapi's answer for an unknown type."""
    _type(args, "srv")
    return {"typedefs": []}


def _time(graph: Graph, args: dict[str, Any]) -> dict[str, Any]:
    now = time_of(graph.now)
    return {"time": {**now, "secs": now["sec"], "nsecs": now["nanosec"]}}


Answer = Callable[[Graph, dict[str, Any]], dict[str, Any]]
#: service name -> (type, request fields, answer)
SERVICES: dict[str, tuple[str, tuple[str, ...], Answer]] = {
    "/rosapi/topics": ("Topics", (), lambda g, a: {"topics": sorted(g.topics),
                                                   "types": [g.topics[t] for t in sorted(g.topics)]}),
    "/rosapi/topic_type": ("TopicType", ("topic",), lambda g, a: {"type": g.topics.get(_name(a, "topic"), "")}),
    "/rosapi/topics_for_type": ("TopicsForType", ("type",), lambda g, a: {
        "topics": sorted(t for t, kind in g.topics.items() if kind == _type(a, "msg"))}),
    "/rosapi/publishers": ("Publishers", ("topic",), lambda g, a: {
        "publishers": [g.node] if _name(a, "topic") in g.published else []}),
    "/rosapi/subscribers": ("Subscribers", ("topic",), lambda g, a: {
        "subscribers": [g.node] if _name(a, "topic") in g.subscribed else []}),
    "/rosapi/services": ("Services", (), lambda g, a: {"services": sorted(g.services)}),
    "/rosapi/service_type": ("ServiceType", ("service",), lambda g, a: {
        "type": g.services.get(_name(a, "service"), "")}),
    "/rosapi/services_for_type": ("ServicesForType", ("type",), lambda g, a: {
        "services": sorted(s for s, kind in g.services.items() if kind == _type(a, "srv"))}),
    "/rosapi/service_node": ("ServiceNode", ("service",), lambda g, a: {"node": _provider(g, _name(a, "service"))}),
    "/rosapi/service_providers": ("ServiceProviders", ("service",), lambda g, a: {
        "providers": [p] if (p := _provider(g, _name(a, "service"))) else []}),
    "/rosapi/nodes": ("Nodes", (), lambda g, a: {"nodes": sorted({g.node, ROSAPI_NODE})}),
    "/rosapi/node_details": ("NodeDetails", ("node",), _node_details),
    "/rosapi/message_details": ("MessageDetails", ("type",), lambda g, a: {"typedefs": typedefs(_type(a, "msg"))}),
    "/rosapi/service_request_details": ("ServiceRequestDetails", ("type",), _service_details),
    "/rosapi/service_response_details": ("ServiceResponseDetails", ("type",), _service_details),
    "/rosapi/action_servers": ("GetActionServers", (), lambda g, a: {"action_servers": []}),
    "/rosapi/get_time": ("GetTime", (), _time),
    "/rosapi/get_ros_version": ("GetROSVersion", (), lambda g, a: {"version": 2, "distro": g.distro}),
    "/rosapi/get_param_names": ("GetParamNames", (), lambda g, a: {"names": []}),
    "/rosapi/get_param": ("GetParam", ("name", "default_value"), _param),
    "/rosapi/has_param": ("HasParam", ("name",), lambda g, a: {"exists": False}),
}
SERVICE_TYPES = {name: f"rosapi_msgs/srv/{kind}" for name, (kind, _, _) in SERVICES.items()}


def call_rosapi(service: str, graph: Graph, args: dict[str, Any]) -> dict[str, Any]:
    """The answer of the rosapi ``service`` to ``args``.

    :raises ValueError: a request field the service does not have, or of the wrong kind.
    """
    _, fields, answer = SERVICES[service]
    for key in args:
        if key not in fields:
            raise ValueError(f"{SERVICE_TYPES[service]} has no request field {quote_untrusted(key, 60)}")
    return answer(graph, args)
