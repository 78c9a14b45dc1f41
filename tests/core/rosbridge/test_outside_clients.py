"""Clients no one here wrote, against the server: roslibpy itself, and ros-mcp 3.x's frames as its tools
send them (one fresh connection per tool call, the next frame read as the answer)."""

from __future__ import annotations

import threading
import time

import pytest

ROS_MCP_PROBE = {"op": "call_service", "id": "rosapi_detect_rosapi", "service": "/rosapi/get_ros_version", "args": {}}


@pytest.fixture
def ros(robot):
    roslibpy = pytest.importorskip("roslibpy", reason="the rosbridge extra: pip install -e '.[rosbridge]'")
    client = roslibpy.Ros("127.0.0.1", robot.server.port)
    client.run(timeout=5)
    yield client
    client.close()


@pytest.fixture
def scanning(robot):
    """The robot publishes /scan at 20 Hz while the test runs."""
    stop = threading.Event()

    def publish() -> None:
        while not stop.wait(0.05):
            robot.server.publish("/scan", {"ranges": [1.0, float("inf")], "range_max": 8.0})

    thread = threading.Thread(target=publish, daemon=True)
    thread.start()
    yield
    stop.set()
    thread.join()


# -- roslibpy ---------------------------------------------------------------------------------------


def test_roslibpy_subscribes_and_receives_a_served_topic(robot, ros, scanning):
    import roslibpy

    received: list[dict] = []
    topic = roslibpy.Topic(ros, "/scan", "sensor_msgs/LaserScan")
    topic.subscribe(received.append)
    deadline = time.monotonic() + 2
    while not received and time.monotonic() < deadline:
        time.sleep(0.02)
    topic.unsubscribe()
    assert received[0] == {"ranges": [1.0, None], "range_max": 8.0}


def test_roslibpy_publishes_to_an_accepted_topic_and_the_handler_gets_it(robot, ros):
    import roslibpy

    topic = roslibpy.Topic(ros, "/cmd_vel", "geometry_msgs/Twist")
    topic.publish(roslibpy.Message({"linear": {"x": 0.25, "y": 0.0, "z": 0.0}, "angular": {"z": 0.5}}))
    kind, msg, _ = robot.wait_for_commands(1)[0]
    assert kind == "geometry_msgs/msg/Twist" and msg["linear"]["x"] == 0.25 and msg["angular"]["z"] == 0.5


def test_a_refused_roslibpy_message_reaches_no_handler_and_the_connection_goes_on(robot, ros):
    """roslibpy 2.1 has no handler for ``status`` (comm.py): it logs the refusal and carries on."""
    import roslibpy

    topic = roslibpy.Topic(ros, "/cmd_vel", "geometry_msgs/Twist")
    topic.publish(roslibpy.Message({"linear": {"x": "fast"}}))
    topic.publish(roslibpy.Message({"linear": {"x": 0.1}}))
    commands = robot.wait_for_commands(1)
    time.sleep(0.1)
    assert [msg["linear"]["x"] for _, msg, _ in commands] == [0.1] and ros.is_connected


def test_roslibpys_rosapi_helpers_answer(robot, ros):
    """roslibpy 2.1's Ros helpers (ros.py): get_topics, get_topic_type, get_services, get_nodes, ..."""
    assert ros.get_topics() == ["/camera/image_raw/compressed", "/cmd_vel", "/events", "/scan"]
    assert ros.get_topic_type("/scan") == "sensor_msgs/msg/LaserScan"
    assert ros.get_topics_for_type("sensor_msgs/LaserScan") == ["/scan"]
    assert {"/add_two_ints", "/rosapi/topics", "/rosapi/get_ros_version"} <= set(ros.get_services())
    assert ros.get_service_type("/add_two_ints") == "example_interfaces/srv/AddTwoInts"
    assert ros.get_nodes() == ["/rosapi", "/safeembodai_robot"]
    assert ros.get_node_details("/safeembodai_robot")["subscribing"] == ["/cmd_vel"]
    assert abs(ros.get_time().to_sec() - time.time()) < 5  # reads the ROS 1 names secs/nsecs
    details = ros.get_message_details("geometry_msgs/Twist")["typedefs"]
    assert details[0]["fieldnames"] == ["linear", "angular"]
    assert ros.get_params() == []


def test_roslibpy_calls_a_service_and_gets_its_answer_by_id(robot, ros):
    """roslibpy files each answer under the id it sent: an answer without it would never arrive."""
    import roslibpy

    service = roslibpy.Service(ros, "/add_two_ints", "example_interfaces/srv/AddTwoInts")
    assert service.call(roslibpy.ServiceRequest({"a": 20, "b": 22}), timeout=2) == {"sum": 42}
    with pytest.raises(roslibpy.core.ServiceException, match="a and b must be integers"):
        service.call(roslibpy.ServiceRequest({"a": "x"}), timeout=2)


# -- ros-mcp 3.x's frames -------------------------------------------------------------------------


def test_ros_mcps_version_probe_is_answered_by_the_first_frame(robot, connect):
    """connect_to_robot -> detect_rosapi_types (utils/rosapi_types.py:78-108): ROS 2 when version >= 2."""
    client = connect(robot.url)
    client.send(ROS_MCP_PROBE)
    assert client.recv() == {"op": "service_response", "service": "/rosapi/get_ros_version",
                             "id": "rosapi_detect_rosapi", "values": {"version": 2, "distro": "jazzy"},
                             "result": True}


@pytest.mark.parametrize("frame, key, expected", [
    ({"service": "/rosapi/topics", "type": "rosapi_msgs/srv/Topics", "args": {}}, "types",
     ["sensor_msgs/msg/CompressedImage", "geometry_msgs/msg/Twist", "std_msgs/msg/String",
      "sensor_msgs/msg/LaserScan"]),
    ({"service": "/rosapi/topic_type", "type": "rosapi_msgs/srv/TopicType", "args": {"topic": "/cmd_vel"}}, "type",
     "geometry_msgs/msg/Twist"),
    ({"service": "/rosapi/publishers", "type": "rosapi_msgs/srv/Publishers", "args": {"topic": "/scan"}},
     "publishers", ["/safeembodai_robot"]),
    ({"service": "/rosapi/subscribers", "type": "rosapi_msgs/srv/Subscribers", "args": {"topic": "/cmd_vel"}},
     "subscribers", ["/safeembodai_robot"]),
    ({"service": "/rosapi/nodes", "type": "rosapi_msgs/srv/Nodes", "args": {}}, "nodes",
     ["/rosapi", "/safeembodai_robot"]),
    ({"service": "/rosapi/action_servers", "type": "rosapi_msgs/srv/ActionServers", "args": {}}, "action_servers",
     []),
])
def test_ros_mcps_read_only_tools_get_their_answer_as_the_next_frame(robot, connect, frame, key, expected):
    """get_topics, get_topic_type, get_topic_details, get_nodes, get_actions (tools/topics.py, nodes.py,
    actions.py): a fresh connection, one call, the next frame is the answer."""
    client = connect(robot.url)
    client.send({"op": "call_service", "id": "tool_request_1", **frame})
    answer = client.recv()
    assert answer["id"] == "tool_request_1" and answer["result"] is True and answer["values"][key] == expected


def test_ros_mcps_subscribe_once_gets_a_message_within_half_a_second(robot, connect, scanning):
    """subscribe_once (tools/topics.py:344-386): subscribe without an id, read, unsubscribe without one."""
    client = connect(robot.url)
    client.send({"op": "subscribe", "topic": "/scan", "type": "sensor_msgs/msg/LaserScan", "queue_length": 1,
                 "throttle_rate": 0})
    frame = client.recv(0.5)
    assert frame["op"] == "publish" and frame["topic"] == "/scan"
    client.send({"op": "unsubscribe", "topic": "/scan"})
    time.sleep(0.1)
    client.frames_within(0.05)
    assert client.frames_within(0.2) == []


def test_ros_mcps_publish_once_over_three_connections_moves_the_robot(robot, connect):
    """publish_once (tools/topics.py:771-813): advertise and wait 1 s for an error (the connection closes
    on the timeout), publish on a new connection that never advertised, unadvertise on a third."""
    first = connect(robot.url)
    first.send({"op": "advertise", "topic": "/cmd_vel", "type": "geometry_msgs/msg/Twist"})
    assert first.frames_within(0.3) == []
    first.close()
    second = connect(robot.url)
    second.send({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 1.0}}})
    assert second.frames_within(0.3) == []
    second.close()
    third = connect(robot.url)
    third.send({"op": "unadvertise", "topic": "/cmd_vel"})
    assert third.frames_within(0.2) == []
    assert robot.wait_for_commands(1)[0][1]["linear"]["x"] == 1.0
