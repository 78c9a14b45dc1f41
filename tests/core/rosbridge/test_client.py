"""The thread-friendly client, against the server and against a server that sends what it should not."""

from __future__ import annotations

import json
import socket
import threading
import time

import pytest
from aiohttp import web

from safeembodai_core.rosbridge.client import RosbridgeClient
from safeembodai_core.rosbridge.errors import RosbridgeError, ServiceCallError


def eventually(condition, timeout: float = 2.0) -> bool:
    deadline = time.monotonic() + timeout
    while not condition() and time.monotonic() < deadline:
        time.sleep(0.01)
    return condition()


@pytest.fixture
def client(robot):
    with RosbridgeClient(robot.url, timeout=2.0) as connected:
        yield connected


def test_a_subscription_gets_the_servers_messages_until_unsubscribed(robot, client):
    received: list[dict] = []
    subscription = client.subscribe("/scan", "sensor_msgs/msg/LaserScan", received.append)
    assert eventually(lambda: robot.server.clients() == 1)
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [0.5, float("inf")]})
    assert eventually(lambda: received == [{"ranges": [0.5, None]}])
    client.unsubscribe(subscription)
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [0.7]})
    time.sleep(0.1)
    assert received == [{"ranges": [0.5, None]}]


def test_a_published_command_reaches_the_servers_handler(robot, client):
    client.advertise("/cmd_vel", "geometry_msgs/msg/Twist")
    client.publish("/cmd_vel", {"linear": {"x": 0.4, "y": 0.0, "z": 0.0}, "angular": {"x": 0, "y": 0, "z": 0.1}})
    kind, msg, _ = robot.wait_for_commands(1)[0]
    assert kind == "geometry_msgs/msg/Twist" and msg["linear"]["x"] == 0.4 and msg["angular"]["z"] == 0.1


def test_two_clients_talk_through_a_topic_one_advertised(robot, client):
    received: list[dict] = []
    with RosbridgeClient(robot.url) as listener:
        client.advertise("/cmd_vel_in", "geometry_msgs/msg/Twist")
        listener.subscribe("/cmd_vel_in", "geometry_msgs/msg/Twist", received.append)
        time.sleep(0.1)
        client.publish("/cmd_vel_in", {"linear": {"x": 0.3}})
        assert eventually(lambda: len(received) == 1)
    assert received[0]["linear"] == {"x": 0.3, "y": 0.0, "z": 0.0}  # a known type arrives filled in


def test_service_calls_answer_or_raise_with_the_servers_reason(robot, client):
    assert client.call_service("/add_two_ints", {"a": 1, "b": 2}) == {"sum": 3}
    assert client.call_service("/rosapi/get_ros_version")["version"] == 2
    with pytest.raises(ServiceCallError, match="/add_two_ints: /add_two_ints: a and b must be integers"):
        client.call_service("/add_two_ints", {"a": 1})
    with pytest.raises(ServiceCallError, match="service /nowhere does not exist"):
        client.call_service("/nowhere")


def test_a_service_that_does_not_answer_in_time_is_an_error(serve_robot):
    robot = serve_robot()
    robot.server.add_service("/slow", "std_srvs/srv/Trigger", lambda args: time.sleep(0.5) or {})
    with RosbridgeClient(robot.url) as connected:
        with pytest.raises(ServiceCallError, match="/slow: no answer within 0.1 s"):
            connected.call_service("/slow", timeout=0.1)


def test_refusals_come_back_as_status_messages(robot):
    statuses = []
    with RosbridgeClient(robot.url, on_status=statuses.append) as connected:
        connected.publish("/cmd_vel", {"linear": {"x": "fast"}})
        assert eventually(lambda: len(statuses) == 1)
    assert statuses[0].level == "error" and "msg.linear.x" in statuses[0].msg


def test_a_lost_connection_is_reported_and_later_calls_raise(serve_robot):
    robot = serve_robot()
    robot.server.add_service("/slow", "std_srvs/srv/Trigger", lambda args: time.sleep(0.6) or {})
    reasons: list[str] = []
    connected = RosbridgeClient(robot.url, on_close=reasons.append).connect()
    failure: list[BaseException] = []

    def call() -> None:
        try:
            connected.call_service("/slow", timeout=3)
        except BaseException as error:
            failure.append(error)

    waiting = threading.Thread(target=call)
    waiting.start()
    time.sleep(0.1)
    robot.server.stop()
    waiting.join(3)
    assert reasons and "the server closed the connection" in reasons[0] and not connected.connected
    assert isinstance(failure[0], RosbridgeError) and "the connection is lost" in str(failure[0])
    with pytest.raises(RosbridgeError, match="is lost"):
        connected.publish("/cmd_vel", {})
    connected.close()
    connected.close()


def test_a_server_that_is_not_there_is_a_clear_error():
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    client = RosbridgeClient(f"ws://127.0.0.1:{port}", timeout=1.0)
    for _ in range(2):  # and it may be tried again
        with pytest.raises(RosbridgeError, match=f"cannot reach rosbridge at ws://127.0.0.1:{port}"):
            client.connect()


def test_after_close_every_call_is_refused(robot):
    connected = RosbridgeClient(robot.url).connect()
    connected.close()
    with pytest.raises(RosbridgeError, match="not connected"):
        connected.publish("/cmd_vel", {})


def test_callbacks_that_raise_or_call_a_service_are_logged_and_the_client_goes_on(robot, client, capsys):
    received: list[dict] = []
    refused: list[BaseException] = []

    def callback(msg: dict) -> None:
        received.append(msg)
        if len(received) == 1:
            raise KeyError("a bug in the callback")
        try:
            client.call_service("/rosapi/topics")
        except RosbridgeError as error:
            refused.append(error)

    client.subscribe("/scan", "sensor_msgs/msg/LaserScan", callback)
    time.sleep(0.1)
    robot.server.publish("/scan", {"ranges": [1.0]})
    time.sleep(0.05)
    robot.server.publish("/scan", {"ranges": [2.0]})
    assert eventually(lambda: len(received) == 2)
    assert "cannot wait inside a subscription callback" in str(refused[0])
    assert "rosbridge_client.callback_failed" in capsys.readouterr().err
    assert client.connected


# -- a server that sends what it should not ---------------------------------------------------------


@pytest.fixture
def hostile_server(aio):
    """A WebSocket server that answers the first frame with bad frames, then one good message."""
    sent = [
        "not json", "[1, 2]", '{"op": "publish", "topic": "/scan", "topic": "/cmd_vel", "msg": {}}',
        '{"op": "publish", "topic": "/scan", "msg": [1]}', '{"op": "publish", "topic": "/scan", "msg": {"r": NaN}}',
        '{"op": "publish", "topic": "/scan", "msg": ' + "[" * 5000 + "]" * 5000 + "}",
        '{"op": "call_service", "service": "/x"}', '{"op": "service_response", "service": "/x", "result": true}',
        b"\x00\x01binary", json.dumps({"op": "publish", "topic": "/scan", "msg": {"ranges": [3.0]}}),
    ]

    async def serve(request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse()
        await ws.prepare(request)
        await ws.receive()
        for frame in sent:
            await (ws.send_bytes(frame) if isinstance(frame, bytes) else ws.send_str(frame))
        async for _ in ws:
            pass
        return ws

    async def start() -> web.AppRunner:
        app = web.Application()
        app.router.add_get("/", serve)
        runner = web.AppRunner(app)
        await runner.setup()
        await web.TCPSite(runner, "127.0.0.1", 0).start()
        return runner

    runner = aio.run(start())
    yield f"ws://127.0.0.1:{runner.addresses[0][1]}"
    aio.run(runner.cleanup())


def test_bad_frames_from_the_server_are_logged_and_dropped_never_raised(hostile_server, capsys):
    received: list[dict] = []
    with RosbridgeClient(hostile_server) as connected:
        connected.subscribe("/scan", "sensor_msgs/msg/LaserScan", received.append)
        assert eventually(lambda: received == [{"ranges": [3.0]}])
        assert connected.connected
    err = capsys.readouterr().err
    assert err.count("rosbridge_client.frame_dropped") == 7
    assert "rosbridge_client.binary_frame_dropped" in err and "rosbridge_client.unexpected_response" in err
