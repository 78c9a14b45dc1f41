"""The rosapi services, answered from the server's graph with rosapi 2.x's field names."""

from __future__ import annotations

import json

import pytest

from safeembodai_core.rosbridge.rosapi import SERVICE_TYPES, Graph, call_rosapi

GRAPH = Graph(node="/robot", distro="jazzy", now=1700000000.25,
              topics={"/scan": "sensor_msgs/msg/LaserScan", "/cmd_vel": "geometry_msgs/msg/Twist",
                      "/chatter": "std_msgs/msg/String"},
              published=frozenset({"/scan", "/chatter"}), subscribed=frozenset({"/cmd_vel"}),
              services={**SERVICE_TYPES, "/add_two_ints": "example_interfaces/srv/AddTwoInts"})


def test_topics_and_their_types_line_up():
    answer = call_rosapi("/rosapi/topics", GRAPH, {})
    assert answer == {"topics": ["/chatter", "/cmd_vel", "/scan"],
                      "types": ["std_msgs/msg/String", "geometry_msgs/msg/Twist", "sensor_msgs/msg/LaserScan"]}


def test_a_topics_type_publishers_and_subscribers():
    assert call_rosapi("/rosapi/topic_type", GRAPH, {"topic": "/scan"}) == {"type": "sensor_msgs/msg/LaserScan"}
    assert call_rosapi("/rosapi/topic_type", GRAPH, {"topic": "scan"}) == {"type": "sensor_msgs/msg/LaserScan"}
    assert call_rosapi("/rosapi/topic_type", GRAPH, {"topic": "/nothing"}) == {"type": ""}
    assert call_rosapi("/rosapi/topics_for_type", GRAPH, {"type": "geometry_msgs/Twist"}) == {"topics": ["/cmd_vel"]}
    assert call_rosapi("/rosapi/publishers", GRAPH, {"topic": "/scan"}) == {"publishers": ["/robot"]}
    assert call_rosapi("/rosapi/subscribers", GRAPH, {"topic": "/scan"}) == {"subscribers": []}
    assert call_rosapi("/rosapi/subscribers", GRAPH, {"topic": "/cmd_vel"}) == {"subscribers": ["/robot"]}


def test_services_nodes_and_who_provides_what():
    services = call_rosapi("/rosapi/services", GRAPH, {})["services"]
    assert "/add_two_ints" in services and "/rosapi/topics" in services and services == sorted(services)
    assert call_rosapi("/rosapi/service_type", GRAPH, {"service": "/rosapi/topics"}) == \
        {"type": "rosapi_msgs/srv/Topics"}
    assert call_rosapi("/rosapi/services_for_type", GRAPH, {"type": "example_interfaces/AddTwoInts"}) == \
        {"services": ["/add_two_ints"]}
    assert call_rosapi("/rosapi/service_node", GRAPH, {"service": "/add_two_ints"}) == {"node": "/robot"}
    assert call_rosapi("/rosapi/service_providers", GRAPH, {"service": "/rosapi/nodes"}) == {"providers": ["/rosapi"]}
    assert call_rosapi("/rosapi/nodes", GRAPH, {}) == {"nodes": ["/robot", "/rosapi"]}
    robot = call_rosapi("/rosapi/node_details", GRAPH, {"node": "/robot"})
    assert robot == {"subscribing": ["/cmd_vel"], "publishing": ["/chatter", "/scan"], "services": ["/add_two_ints"]}
    assert "/rosapi/topics" in call_rosapi("/rosapi/node_details", GRAPH, {"node": "/rosapi"})["services"]


def test_the_version_probe_and_the_time():
    """ros-mcp 3.x probes ``get_ros_version`` first (utils/rosapi_types.py); roslibpy reads secs/nsecs."""
    assert call_rosapi("/rosapi/get_ros_version", GRAPH, {}) == {"version": 2, "distro": "jazzy"}
    assert call_rosapi("/rosapi/get_time", GRAPH, {}) == {
        "time": {"sec": 1700000000, "nanosec": 250000000, "secs": 1700000000, "nsecs": 250000000}}


def test_message_details_and_what_is_empty_here():
    twist = call_rosapi("/rosapi/message_details", GRAPH, {"type": "geometry_msgs/Twist"})["typedefs"]
    assert [t["type"] for t in twist] == ["geometry_msgs/msg/Twist", "geometry_msgs/msg/Vector3"]
    assert call_rosapi("/rosapi/service_request_details", GRAPH, {"type": "rosapi_msgs/srv/Topics"}) == \
        {"typedefs": []}
    assert call_rosapi("/rosapi/action_servers", GRAPH, {}) == {"action_servers": []}
    assert call_rosapi("/rosapi/get_param_names", GRAPH, {}) == {"names": []}
    assert call_rosapi("/rosapi/has_param", GRAPH, {"name": "/robot:x"}) == {"exists": False}


@pytest.mark.parametrize("default, value", [("", '""'), ("5", "5"), ('{"a": [1]}', '{"a": [1]}'), ("abc", '"abc"')])
def test_a_parameter_that_does_not_exist_answers_its_default_as_rosapi_does(default, value):
    answer = call_rosapi("/rosapi/get_param", GRAPH, {"name": "/robot:x", "default_value": default})
    assert json.loads(answer["value"]) == json.loads(value)


@pytest.mark.parametrize("service, args, reason", [
    ("/rosapi/topics", {"type": "x"}, 'rosapi_msgs/srv/Topics has no request field "type"'),
    ("/rosapi/topic_type", {"topic": 5}, "the field 'topic' must be text"),
    ("/rosapi/topic_type", {"topic": "/a/"}, "is not a valid ROS name"),
    ("/rosapi/message_details", {"type": "Twist"}, "is not a ROS msg type"),
])
def test_a_bad_request_is_a_value_error(service, args, reason):
    with pytest.raises(ValueError, match=reason):
        call_rosapi(service, GRAPH, args)
