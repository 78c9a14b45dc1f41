"""The server over a real WebSocket: the ops, the refusals, the limits, several clients at once.

Clients here are plain aiohttp WebSockets and raw TCP sockets, so each test sends exactly the bytes
it means to; a refusal is a ``status`` message at level ``error`` carrying the frame's id, or the
connection closed, and every test checks that the server goes on serving (another client, a new one).
"""

from __future__ import annotations

import json
import logging
import socket
import time

import pytest

from safeembodai_core.logs import configure_logging
from safeembodai_core.rosbridge.errors import RosbridgeError
from safeembodai_core.rosbridge.server import RosbridgeServer

TWIST = "geometry_msgs/msg/Twist"


def status(client, frame):
    client.send(frame)
    answer = client.recv()
    assert answer["op"] == "status" and answer["level"] == "error", answer
    return answer


def still_served(robot, connect):
    """A new client subscribes and receives: the server is still up."""
    fresh = connect(robot.url)
    fresh.send({"op": "subscribe", "topic": "/scan", "id": "check"})
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [2.0]})
    assert fresh.recv()["msg"] == {"ranges": [2.0]}


# -- topics -----------------------------------------------------------------------------------------


def test_a_subscriber_receives_what_the_server_publishes_with_inf_as_null(robot, connect):
    client = connect(robot.url)
    client.send({"op": "subscribe", "topic": "/scan", "type": "sensor_msgs/LaserScan", "id": "s"})
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [1.5, float("inf"), float("nan")], "range_max": 12.0})
    frame = client.recv()
    assert frame == {"op": "publish", "topic": "/scan", "msg": {"ranges": [1.5, None, None], "range_max": 12.0}}


def test_a_latched_topic_sends_its_last_message_on_subscribe(robot, connect):
    """ros-mcp's subscribe_once waits 0.5 s: a sparse topic must answer at once."""
    robot.server.publish("/events", {"data": "collision"})
    client = connect(robot.url)
    client.send({"op": "subscribe", "topic": "/events"})
    assert client.recv(0.5)["msg"] == {"data": "collision"}


def test_a_published_command_reaches_the_handler_checked_and_filled(robot, connect):
    client = connect(robot.url)
    client.send({"op": "advertise", "topic": "/cmd_vel", "type": "geometry_msgs/Twist"})
    client.send({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 0.5}}})
    kind, msg, who = robot.wait_for_commands(1)[0]
    assert kind == TWIST and msg["linear"] == {"x": 0.5, "y": 0.0, "z": 0.0} and msg["angular"]["z"] == 0.0
    assert who.startswith("c") and "@127.0.0.1:" in who
    assert client.frames_within(0.1) == []  # a publish is not answered


def test_a_publish_without_advertise_to_an_accepted_topic_is_taken_with_the_type_it_fits(robot, connect):
    """ros-mcp 3.x's publish_once publishes on a connection that never advertised (topics.py:792)."""
    client = connect(robot.url)
    client.send({"op": "publish", "topic": "/cmd_vel", "msg": {"header": {"frame_id": "base"}, "twist": {}}})
    client.send({"op": "publish", "topic": "cmd_vel", "msg": {"linear": {"x": 0.1}}})
    commands = robot.wait_for_commands(2)
    assert [kind for kind, _, _ in commands] == ["geometry_msgs/msg/TwistStamped", TWIST]


def test_a_handlers_value_error_goes_back_as_a_status_error_with_the_frames_id(robot, connect):
    client = connect(robot.url)
    answer = status(client, {"op": "publish", "topic": "/cmd_vel", "id": "p1", "msg": {"linear": {"x": 9.0}}})
    assert answer["id"] == "p1" and answer["msg"] == "/cmd_vel: linear.x above 5 m/s is refused"
    crash = status(client, {"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": -500.0}}})
    assert crash["msg"] == "/cmd_vel: the server failed to handle this"  # no traceback to the client
    client.send({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 1.0}}})
    assert robot.wait_for_commands(1)[0][1]["linear"]["x"] == 1.0


@pytest.mark.parametrize("frame, reason", [
    ({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": "fast"}}},
     "msg.linear.x: a number (float64) is required, not text"),
    ({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": None}}}, "msg.linear.x"),
    ({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 1e300, "y": [1]}}}, "msg.linear.y"),
    ({"op": "publish", "topic": "/cmd_vel", "msg": {"data": "go"}}, 'has no field "data"'),
    ({"op": "publish", "topic": "/CMD_VEL", "msg": {}}, "/CMD_VEL was never advertised by this client"),
    ({"op": "publish", "topic": "/somewhere", "msg": {}}, "/somewhere was never advertised by this client"),
    ({"op": "publish", "topic": "/scan", "msg": {}}, "/scan is published by this server"),
    ({"op": "advertise", "topic": "/scan", "type": "sensor_msgs/msg/LaserScan"}, "/scan is published by this server"),
    ({"op": "advertise", "topic": "/cmd_vel", "type": "std_msgs/msg/String"},
     "/cmd_vel takes geometry_msgs/msg/Twist or geometry_msgs/msg/TwistStamped, not std_msgs/msg/String"),
    ({"op": "subscribe", "topic": "/scan", "type": "sensor_msgs/msg/Image"},
     "/scan is sensor_msgs/msg/LaserScan, not sensor_msgs/msg/Image"),
    ({"op": "subscribe", "topic": "/nothing"}, "/nothing does not exist: give its type"),
    ({"op": "subscribe", "topic": "/scan", "queue_length": 10_000}, "queue_length 10000 is more than the limit"),
    ({"op": "subscribe", "topic": "/scan", "compression": "cbor"}, "compression \"cbor\" is not supported"),
    ({"op": "fragment", "id": "f", "data": "{", "num": 0, "total": 2}, "fragmented frames are not supported"),
    ({"op": "call_service", "service": "/a", "args": [1]}, "args as a list is not supported"),
    ({"op": "teleport", "to": "/mars"}, 'unknown op "teleport"'),
    ({"op": "subscribe", "id": 4}, "the field 'topic' is missing"),
    ({"op": "service_response", "service": "/x", "result": True}, "sent by a server, not by a client"),
])
def test_each_refusal_is_a_status_error_and_the_connection_goes_on(robot, connect, frame, reason):
    client = connect(robot.url)
    answer = status(client, {**frame, "id": "x1"})
    assert reason in answer["msg"] and answer["id"] == "x1"
    assert robot.commands == []
    client.send({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 0.2}}})
    assert len(robot.wait_for_commands(1)) == 1


@pytest.mark.parametrize("text, reason", [
    ("{not json", "frame is not JSON"),
    ("[1, 2, 3]", "frame must be a JSON object, not list"),
    ('{"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": NaN}}}', "NaN is not JSON"),
    ('{"op": "publish", "topic": "/x", "topic": "/cmd_vel", "msg": {}}', 'key "topic" appears more than once'),
])
def test_a_frame_that_is_not_one_json_object_gets_a_status_error(robot, connect, text, reason):
    client = connect(robot.url)
    assert reason in status(client, text)["msg"]
    assert robot.commands == []
    still_served(robot, connect)


def test_a_binary_frame_is_refused_cbor_is_not_spoken(robot, connect):
    client = connect(robot.url)
    client.send_bytes(b"\xa1\x62op\x67publish")
    answer = client.recv()
    assert answer["op"] == "status" and "binary frames (CBOR, BSON) are not supported" in answer["msg"]


def test_clients_publish_to_each_other_on_a_topic_one_advertised(robot, connect):
    talker, listener = connect(robot.url), connect(robot.url)
    talker.send({"op": "advertise", "topic": "/chatter", "type": "std_msgs/String"})
    time.sleep(0.05)
    listener.send({"op": "subscribe", "topic": "/chatter", "type": "std_msgs/msg/String"})
    time.sleep(0.05)
    talker.send({"op": "publish", "topic": "/chatter", "msg": {"data": "hello"}})
    assert listener.recv() == {"op": "publish", "topic": "/chatter", "msg": {"data": "hello"}}
    assert "(std_msgs/msg/String): " not in status(talker, {"op": "publish", "topic": "/chatter", "msg": {"d": 1}})
    listener.send({"op": "call_service", "service": "/rosapi/topics", "id": 1})
    assert "/chatter" in listener.recv()["values"]["topics"]
    assert "already advertised as std_msgs/msg/String" in status(
        listener, {"op": "advertise", "topic": "/chatter", "type": "std_msgs/msg/Header"})["msg"]
    talker.close()
    time.sleep(0.1)
    listener.send({"op": "call_service", "service": "/rosapi/topics", "id": 2})
    assert "/chatter" not in listener.recv()["values"]["topics"]


def test_several_subscriptions_of_one_client_and_unsubscribe_by_id_or_all(robot, connect):
    client = connect(robot.url)
    client.send({"op": "subscribe", "topic": "/scan", "id": "a"})
    client.send({"op": "subscribe", "topic": "/scan", "id": "b"})
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [1.0]})
    assert len(client.frames_within(0.2)) == 1  # one message per topic, however many subscriptions
    client.send({"op": "unsubscribe", "topic": "/scan", "id": "a"})
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [2.0]})
    assert [f["msg"] for f in client.frames_within(0.2)] == [{"ranges": [2.0]}]
    client.send({"op": "unsubscribe", "topic": "/scan"})
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [3.0]})
    assert client.frames_within(0.2) == []


def test_warnings_are_sent_only_to_a_client_that_asks_for_them(robot, connect):
    client = connect(robot.url)
    client.send({"op": "unsubscribe", "topic": "/scan", "id": "none"})
    client.send({"op": "unadvertise", "topic": "/cmd_vel"})
    assert client.frames_within(0.2) == []  # ros-mcp unadvertises on a fresh connection: nothing unasked
    client.send({"op": "set_level", "level": "warning"})
    client.send({"op": "unadvertise", "topic": "/cmd_vel", "id": "u"})
    answer = client.recv()
    assert answer == {"op": "status", "level": "warning", "msg": "/cmd_vel was not advertised by this client",
                      "id": "u"}
    client.send({"op": "set_level", "level": "none"})
    client.send({"op": "teleport"})
    assert client.frames_within(0.2) == []


def test_throttle_rate_spaces_the_messages_a_client_gets(robot, connect):
    client = connect(robot.url)
    client.send({"op": "subscribe", "topic": "/scan", "throttle_rate": 100})
    time.sleep(0.05)
    for n in range(25):
        robot.server.publish("/scan", {"ranges": [float(n)]})
        time.sleep(0.01)
    received = client.frames_within(0.3)
    assert 2 <= len(received) <= 4, received  # 250 ms of messages at most one per 100 ms


def test_queue_length_keeps_the_newest_messages_of_a_throttled_topic(robot, connect):
    client = connect(robot.url)
    client.send({"op": "subscribe", "topic": "/scan", "throttle_rate": 100, "queue_length": 3})
    time.sleep(0.05)
    for n in range(10):
        robot.server.publish("/scan", {"ranges": [float(n)]})
    received = [frame["msg"]["ranges"][0] for frame in client.frames_within(0.6)]
    assert received[-3:] == [7.0, 8.0, 9.0] and len(received) <= 4, received


# -- services ---------------------------------------------------------------------------------------


def test_a_service_call_is_answered_with_its_id_values_and_result(robot, connect):
    client = connect(robot.url)
    assert client.call("/add_two_ints", {"a": 2, "b": 3}, call_id="call_service:/add_two_ints:7") == {
        "op": "service_response", "service": "/add_two_ints", "id": "call_service:/add_two_ints:7",
        "values": {"sum": 5}, "result": True}
    refused = client.call("/add_two_ints", {"a": "2"}, call_id=8)
    assert refused == {"op": "service_response", "service": "/add_two_ints", "id": 8,
                       "values": "/add_two_ints: a and b must be integers", "result": False}
    missing = client.call("/launch", {})
    assert missing["result"] is False and missing["values"] == "service /launch does not exist"
    assert client.frames_within(0.1) == []  # one frame per call: ros-mcp reads the next frame as the answer


def test_the_rosapi_services_see_client_subscriptions_and_refuse_bad_requests(robot, connect):
    client = connect(robot.url)
    client.send({"op": "subscribe", "topic": "/scan"})
    details = client.call("/rosapi/node_details", {"node": "/safeembodai_robot"})["values"]
    assert details["publishing"] == ["/camera/image_raw/compressed", "/events", "/scan"]
    assert details["subscribing"] == ["/cmd_vel", "/scan"] and details["services"] == ["/add_two_ints"]
    bad = client.call("/rosapi/topic_type", {"topic": ["/scan"]})
    assert bad["result"] is False and "must be text" in bad["values"]


# -- limits and hostile clients ---------------------------------------------------------------------


def test_a_subscribe_storm_is_capped_per_client_and_others_are_served(serve_robot, connect):
    robot = serve_robot(max_subscriptions=5)
    stormer, other = connect(robot.url), connect(robot.url)
    for n in range(40):
        stormer.send({"op": "subscribe", "topic": "/scan", "id": f"s{n}"})
    refusals = [f for f in stormer.frames_within(0.3) if f["op"] == "status"]
    assert len(refusals) == 35 and "at most 5 subscriptions" in refusals[0]["msg"]
    assert refusals[0]["id"] == "s5"
    still_served(robot, connect)
    other.send({"op": "subscribe", "topic": "/scan"})
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [1.0]})
    assert other.recv()["msg"] == {"ranges": [1.0]}


def test_a_frame_bigger_than_the_limit_closes_that_connection_only(serve_robot, connect):
    robot = serve_robot(max_frame_bytes=64 * 1024)
    big, other = connect(robot.url), connect(robot.url)
    big.send({"op": "publish", "topic": "/cmd_vel", "msg": {"pad": "x" * 200_000}})
    assert big.closed_with() == 1009  # WebSocket's "message too big"
    assert robot.commands == []
    other.send({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 0.3}}})
    assert len(robot.wait_for_commands(1)) == 1
    still_served(robot, connect)


def test_a_client_that_disconnects_mid_frame_is_forgotten(robot, connect, wire):
    sock = wire.socket(robot.server.port)
    assert wire.wait_until(lambda: robot.server.clients() == 1)
    payload = json.dumps({"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 1.0}}}).encode()
    sock.sendall(wire.frame(payload, declared=1000)[:30])  # a header promising 1000 bytes, then 24 of them
    sock.close()
    assert wire.wait_until(lambda: robot.server.clients() == 0)
    assert robot.commands == []
    still_served(robot, connect)


def test_a_client_that_never_reads_is_closed_and_never_blocks_the_others_or_the_publisher(robot, connect, wire):
    """Big camera frames to a client whose socket is never read: the publisher's calls stay quick, a
    reading client keeps up, and the stuck one is closed after send_timeout (0.5 s here)."""
    stuck = wire.socket(robot.server.port, receive_buffer=4096)
    stuck.sendall(wire.frame(json.dumps({"op": "subscribe", "topic": "/camera/image_raw/compressed"}).encode()))
    reader = connect(robot.url)
    reader.send({"op": "subscribe", "topic": "/camera/image_raw/compressed"})
    assert wire.wait_until(lambda: robot.server.clients() == 2)
    time.sleep(0.05)
    image = {"format": "jpeg", "data": "A" * 400_000}
    slowest, received = 0.0, 0
    for n in range(30):
        started = time.perf_counter()
        robot.server.publish("/camera/image_raw/compressed", {**image, "format": f"jpeg{n}"})
        slowest = max(slowest, time.perf_counter() - started)
        received += len(reader.frames_within(0.03))
    assert slowest < 0.2, f"publish() blocked for {slowest:.3f} s"  # blocking would last send_timeout
    assert received >= 10
    assert wire.wait_until(lambda: robot.server.clients() == 1, timeout=3.0)
    still_served(robot, connect)


def test_a_client_that_asks_without_reading_the_answers_is_closed(serve_robot, connect, wire):
    """Its socket is full (big camera frames it never reads); the calls it goes on sending pile up
    replies until ``send_queue`` (16 here) is passed, and it is closed long before ``send_timeout``."""
    robot = serve_robot(send_queue=16, send_timeout=30.0)
    stuck = wire.socket(robot.server.port, receive_buffer=4096)
    stuck.sendall(wire.frame(json.dumps({"op": "subscribe", "topic": "/camera/image_raw/compressed"}).encode()))
    assert wire.wait_until(lambda: robot.server.clients() == 1)
    time.sleep(0.05)
    for n in range(30):
        robot.server.publish("/camera/image_raw/compressed", {"format": f"jpeg{n}", "data": "A" * 400_000})
    time.sleep(0.2)
    call = wire.frame(json.dumps({"op": "call_service", "service": "/rosapi/nodes", "id": 1}).encode())
    started = time.monotonic()
    try:
        for _ in range(100):
            stuck.sendall(call)
    except OSError:
        pass  # closed under it
    assert wire.wait_until(lambda: robot.server.clients() == 0, timeout=5.0)
    assert time.monotonic() - started < 5.0
    still_served(robot, connect)


def test_too_many_clients_are_answered_503_and_a_plain_http_request_400(serve_robot, connect):
    robot = serve_robot(max_clients=1)
    connect(robot.url)
    with pytest.raises(Exception, match="503"):
        connect(robot.url)
    with socket.create_connection(("127.0.0.1", robot.server.port), timeout=2) as plain:
        plain.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
        assert plain.recv(100).startswith(b"HTTP/1.1 400")


def test_bad_http_is_answered_400_and_logged_without_a_traceback(robot, connect, capsys):
    """aiohttp logs a bad request with its traceback; the server makes it one structlog line, and
    nothing reaches the application's own logging (here: a handler on the root logger)."""
    seen: list[logging.LogRecord] = []

    class Catcher(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            seen.append(record)

    root, catcher = logging.getLogger(), Catcher()
    root.addHandler(catcher)
    configure_logging("info")
    try:
        for request in (b"\x16\x03\x01\x02\x00\x01\x00\x01\xfc\x03\x03\r\n\r\n",  # TLS on the port
                        b"GET / HTTP/1.1\r\nUpgrade: websocket\r\n\r\n"):  # no Host
            with socket.create_connection(("127.0.0.1", robot.server.port), timeout=2) as plain:
                plain.sendall(request)
                assert plain.recv(100).startswith(b"HTTP/1.0 400")
    finally:
        root.removeHandler(catcher)
        configure_logging("warning")
    assert [record for record in seen if record.exc_info] == []
    err = capsys.readouterr().err
    assert "rosbridge.bad_http_request" in err and "Traceback" not in err
    still_served(robot, connect)


# -- lifecycle --------------------------------------------------------------------------------------


def test_a_port_in_use_is_a_clear_error(robot):
    second = RosbridgeServer(port=robot.server.port)
    with pytest.raises(RosbridgeError, match=f"cannot serve rosbridge on 127.0.0.1:{robot.server.port}: .*in use"):
        second.start()
    second.stop()


def test_stop_closes_every_connection_and_is_idempotent(connect):
    server = RosbridgeServer(port=0)
    server.offer_topic("/scan", "sensor_msgs/msg/LaserScan")
    server.start()
    client = connect(f"ws://127.0.0.1:{server.port}")
    client.send({"op": "subscribe", "topic": "/scan"})
    server.stop()
    assert client.closed_with() == 1001  # going away
    server.stop()
    server.publish("/scan", {"ranges": []})  # after stop: nothing to do, no error
    with pytest.raises(RosbridgeError, match="already started"):
        server.start()


def test_what_the_process_registers_is_checked():
    server = RosbridgeServer(port=0)
    server.offer_topic("scan", "sensor_msgs/LaserScan")
    with pytest.raises(ValueError, match="already offered"):
        server.offer_topic("/scan", "sensor_msgs/msg/LaserScan")
    with pytest.raises(ValueError, match="must accept known message types"):
        server.accept_topic("/joy", ["sensor_msgs/msg/Joy"], lambda *a: None)
    with pytest.raises(ValueError, match="already exists"):
        server.add_service("/rosapi/topics", "rosapi_msgs/srv/Topics", dict)
    with pytest.raises(ValueError, match="is not offered"):
        server.publish("/odom", {})


def handshake_status(port: int, origin: str | None) -> bytes:
    """The status line a WebSocket handshake from a page of ``origin`` (None: no page) is answered with."""
    lines = ["GET / HTTP/1.1", f"Host: 127.0.0.1:{port}", "Upgrade: websocket", "Connection: Upgrade",
             "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==", "Sec-WebSocket-Version: 13"]
    if origin is not None:
        lines.append(f"Origin: {origin}")
    with socket.create_connection(("127.0.0.1", port), timeout=2) as plain:
        plain.sendall(("\r\n".join(lines) + "\r\n\r\n").encode())
        return plain.recv(100).split(b"\r\n")[0]


def test_a_page_of_another_origin_cannot_drive_the_robot(serve_robot):
    """A WebSocket is not bound by the same-origin rule: without this, any page a local browser opened
    (``https://evil.example``, another local server, a DNS-rebound name) could publish to /cmd_vel."""
    robot = serve_robot(allowed_origins=["https://dashboard.example:8080"])
    port = robot.server.port
    for origin in ("https://evil.example", "http://127.0.0.1:8000", f"http://rebound.example:{port}", "null"):
        assert handshake_status(port, origin) == b"HTTP/1.1 403 Forbidden", origin
    for origin in (None, f"http://127.0.0.1:{port}", f"http://localhost:{port}", "https://dashboard.example:8080/"):
        assert handshake_status(port, origin) == b"HTTP/1.1 101 Switching Protocols", origin
