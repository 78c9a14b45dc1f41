"""The one strict reader of rosbridge frames, and the writer of the server's own."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.rosbridge.frames import (MAX_DEPTH, Advertise, CallService, FrameError, Publish, ServiceResponse,
                                               SetLevel, Status, Subscribe, Unadvertise, Unsubscribe, encode_frame,
                                               read_frame)


def test_each_op_reads_into_its_typed_frame():
    assert read_frame('{"op": "advertise", "topic": "/cmd_vel", "type": "geometry_msgs/msg/Twist", "id": 7}') == \
        Advertise("/cmd_vel", "geometry_msgs/msg/Twist", 7)
    assert read_frame('{"op": "unadvertise", "topic": "/cmd_vel"}') == Unadvertise("/cmd_vel")
    assert read_frame('{"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 1}}, "latch": false}') == \
        Publish("/cmd_vel", {"linear": {"x": 1}})
    assert read_frame('{"op": "subscribe", "topic": "/scan", "type": "sensor_msgs/msg/LaserScan", "id": "s1", '
                      '"throttle_rate": 100, "queue_length": 2, "compression": "none", "fragment_size": null}') == \
        Subscribe("/scan", "sensor_msgs/msg/LaserScan", 100, 2, "s1")
    assert read_frame('{"op": "unsubscribe", "topic": "/scan", "id": "s1"}') == Unsubscribe("/scan", "s1")
    assert read_frame('{"op": "call_service", "service": "/rosapi/topics", "type": "rosapi_msgs/srv/Topics", '
                      '"args": {}, "id": "c"}') == CallService("/rosapi/topics", {}, "c")
    assert read_frame('{"op": "call_service", "service": "/rosapi/topics", "args": []}') == \
        CallService("/rosapi/topics", {})
    assert read_frame('{"op": "service_response", "service": "/x", "result": false, "values": "no"}') == \
        ServiceResponse("/x", False, "no")
    assert read_frame('{"op": "set_level", "level": "warning"}') == SetLevel("warning")
    assert read_frame('{"op": "status", "level": "error", "msg": "bad", "id": 3}') == Status("error", "bad", 3)


def test_ros1_types_and_relative_names_are_the_same_as_ros2_and_absolute_ones():
    """roslibpy users write ``geometry_msgs/Twist``; ``cmd_vel`` is ``/cmd_vel`` in the root namespace."""
    frame = read_frame('{"op": "advertise", "topic": "cmd_vel", "type": "geometry_msgs/Twist"}')
    assert frame == Advertise("/cmd_vel", "geometry_msgs/msg/Twist")


@pytest.mark.parametrize("text, reason", [
    ("not json", "not JSON"),
    ("[1, 2]", "must be a JSON object, not list"),
    ('"publish"', "must be a JSON object, not str"),
    ('{"topic": "/scan"}', "has no 'op'"),
    ('{"op": 3}', "has no 'op'"),
    ('{"op": "launch_missiles"}', "unknown op"),
    ('{"op": "fragment", "id": "f", "data": "{", "num": 0, "total": 2}', "fragmented frames are not supported"),
    ('{"op": "png", "data": "x"}', "PNG-compressed frames are not supported"),
    ('{"op": "advertise_service", "service": "/s", "type": "a/B"}', "clients cannot provide services"),
    ('{"op": "send_action_goal", "action": "/a"}', "actions are not supported"),
    ('{"op": "subscribe"}', "the field 'topic' is missing"),
    ('{"op": "advertise", "topic": "/a"}', "the field 'type' is missing"),
    ('{"op": "publish", "topic": "/a"}', "the field 'msg' is missing"),
    ('{"op": "publish", "topic": "/a", "msg": [1]}', "'msg' must be dict, not list"),
    ('{"op": "publish", "topic": 5, "msg": {}}', "'topic' must be str, not int"),
    ('{"op": "subscribe", "topic": "/a", "throttle_rate": -1}', "throttle_rate must be between 0"),
    ('{"op": "subscribe", "topic": "/a", "queue_length": true}', "'queue_length' must be int, not bool"),
    ('{"op": "subscribe", "topic": "/a", "queue_length": 1.5}', "'queue_length' must be int, not float"),
    ('{"op": "subscribe", "topic": "/a", "compression": "cbor"}', 'compression "cbor" is not supported'),
    ('{"op": "call_service", "service": "/s", "args": [1, 2]}', "args as a list is not supported"),
    ('{"op": "set_level", "level": "debug"}', "level must be one of"),
    ('{"op": "publish", "topic": "/a", "msg": {}, "id": [1]}', "id must be text"),
    ('{"op": "publish", "topic": "/cmd_vel/", "msg": {}}', "is not a valid ROS name"),
    ('{"op": "publish", "topic": "//cmd_vel", "msg": {}}', "is not a valid ROS name"),
    ('{"op": "publish", "topic": "~/cmd_vel", "msg": {}}', "is not a valid ROS name"),
    ('{"op": "publish", "topic": "/cmd vel", "msg": {}}', "is not a valid ROS name"),
    ('{"op": "advertise", "topic": "/a", "type": "Twist"}', "is not a ROS msg type"),
    ('{"op": "advertise", "topic": "/a", "type": "geometry_msgs/srv/Twist"}', "is not a ROS msg type"),
])
def test_what_is_refused_is_refused_with_a_reason(text, reason):
    with pytest.raises(FrameError) as refused:
        read_frame(text)
    assert reason in str(refused.value)
    assert isinstance(refused.value, SafeEmbodAIError)


@pytest.mark.parametrize("text, reason", [
    ('{"op": "publish", "topic": "/a", "topic": "/cmd_vel", "msg": {}}', 'key "topic" appears more than once'),
    ('{"op": "publish", "topic": "/a", "msg": {"x": 1, "x": 2}}', 'key "x" appears more than once'),
    ('{"op": "publish", "topic": "/a", "msg": {"x": NaN}}', "NaN is not JSON"),
    ('{"op": "publish", "topic": "/a", "msg": {"x": -Infinity}}', "-Infinity is not JSON"),
    ('{"op": "publish", "topic": "/a", "msg": {"x": 1e999}}', "is not a finite float64"),
    ('{"op": "publish", "topic": "/a", "msg": {"x": 18446744073709551616}}', "is beyond 64 bits"),
    ('{"op": "publish", "topic": "/a", "msg": {"x": ' + "9" * 5000 + "}}", "is beyond 64 bits"),
    ('{"op": "publish", "topic": "/a", "msg": {"x": "\\ud800"}}', "lone surrogate"),
    ('{"op": "publish", "topic": "/a", "msg": {"x": "\ud800"}}', "lone surrogate"),
])
def test_json_that_means_two_things_or_no_number_is_refused(text, reason):
    with pytest.raises(FrameError, match=reason):
        read_frame(text)


def test_nesting_is_limited_without_a_recursion_error():
    shallow = {"op": "publish", "topic": "/a", "msg": {}}  # two levels of objects
    inner = shallow["msg"]
    for _ in range(MAX_DEPTH - 2):
        inner["a"] = {}
        inner = inner["a"]
    assert isinstance(read_frame(json.dumps(shallow)), Publish)  # MAX_DEPTH levels
    inner["a"] = [1]
    with pytest.raises(FrameError, match="nests deeper than"):
        read_frame(json.dumps(shallow))
    with pytest.raises(FrameError, match="nests deeper than"):
        read_frame('{"op": "publish", "topic": "/a", "msg": {"x": ' + "[" * 100_000 + "]" * 100_000 + "}}")


def test_a_frame_longer_than_the_limit_is_refused_before_it_is_parsed():
    with pytest.raises(FrameError, match="longer than the limit of 100"):
        read_frame('{"op": "publish", "topic": "/a", "msg": {"data": "' + "x" * 200 + '"}}', max_chars=100)


def test_the_refusal_carries_the_frames_id_and_quotes_what_the_client_wrote():
    with pytest.raises(FrameError) as refused:
        read_frame('{"op": "subscribe", "id": "sub-9", "topic": "/a\\u001b[31m"}')
    assert refused.value.frame_id == "sub-9" and refused.value.op == "subscribe"
    assert "\x1b" not in str(refused.value) and "\\u001b" in str(refused.value)
    with pytest.raises(FrameError) as unknown:
        read_frame('{"op": "teleport", "id": 12}')
    assert unknown.value.frame_id == 12


def test_the_writer_sends_inf_and_nan_as_null_bytes_as_base64_and_numpy_as_numbers():
    text = encode_frame({"op": "publish", "topic": "/scan", "msg": {
        "ranges": [1.5, math.inf, -math.inf, math.nan], "data": b"\xff\x00", "n": np.float32(0.5),
        "a": np.array([1.0, np.inf])}})
    assert "Infinity" not in text and "NaN" not in text
    assert json.loads(text)["msg"] == {"ranges": [1.5, None, None, None], "data": "/wA=", "n": 0.5, "a": [1.0, None]}
    assert isinstance(read_frame(text), Publish)  # what the server writes, its own reader reads
    with pytest.raises(TypeError, match="object cannot be sent"):
        encode_frame({"msg": object()})
