"""Messages checked against their type as rosbridge checks them, and rosapi's typedefs of the types."""

from __future__ import annotations

import pytest

from safeembodai_core.rosbridge.messages import MESSAGE_TYPES, MessageError, conform, typedefs

STAMP = {"sec": 12, "nanosec": 500}
ZERO = {"x": 0.0, "y": 0.0, "z": 0.0}


def test_missing_fields_take_their_defaults_as_rosbridge_fills_them():
    """ros-mcp's own example publishes ``{'linear': {'x': 1.0}}``: the rest is zero."""
    assert conform("geometry_msgs/msg/Twist", {"linear": {"x": 1}}, STAMP) == \
        {"linear": {"x": 1, "y": 0.0, "z": 0.0}, "angular": ZERO}
    pose = conform("nav_msgs/msg/Odometry", {}, STAMP)["pose"]
    assert pose["pose"]["orientation"] == {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}  # ROS 2's Quaternion default
    assert pose["covariance"] == [0.0] * 36


def test_a_missing_header_or_stamp_takes_the_servers_time():
    stamped = conform("geometry_msgs/msg/TwistStamped", {"twist": {}}, STAMP)
    assert stamped["header"] == {"stamp": STAMP, "frame_id": ""}
    given = conform("geometry_msgs/msg/TwistStamped", {"header": {"frame_id": "base_link"}}, STAMP)
    assert given["header"] == {"stamp": STAMP, "frame_id": "base_link"}
    explicit = conform("geometry_msgs/msg/TwistStamped", {"header": {"stamp": {"sec": 1}}}, STAMP)
    assert explicit["header"]["stamp"] == {"sec": 1, "nanosec": 0}


@pytest.mark.parametrize("type_name, msg, reason", [
    ("geometry_msgs/msg/Twist", {"linear": {"x": "fast"}}, "msg.linear.x: a number (float64) is required, not text"),
    ("geometry_msgs/msg/Twist", {"linear": {"x": None}}, "msg.linear.x: a number (float64) is required, not null"),
    ("geometry_msgs/msg/Twist", {"linear": {"x": True}}, "msg.linear.x: a number (float64) is required, not a bool"),
    ("geometry_msgs/msg/Twist", {"linear": [1, 0, 0]}, "msg.linear: a geometry_msgs/msg/Vector3 must be an object"),
    ("geometry_msgs/msg/Twist", {"linear": {"w": 1}}, 'msg.linear: geometry_msgs/msg/Vector3 has no field "w"'),
    ("geometry_msgs/msg/Twist", {"twist": {}}, 'msg: geometry_msgs/msg/Twist has no field "twist"'),
    ("geometry_msgs/msg/TwistStamped", {"linear": {"x": 1}}, "has no field \"linear\""),
    ("geometry_msgs/msg/Twist", [], "msg: a geometry_msgs/msg/Twist must be an object, not an array"),
    ("sensor_msgs/msg/LaserScan", {"range_max": 1e39}, "msg.range_max: 1e+39 is beyond the range of float32"),
    ("sensor_msgs/msg/LaserScan", {"ranges": 3.0}, "msg.ranges: an array is required"),
    ("sensor_msgs/msg/LaserScan", {"ranges": [1.0, "x"]}, "msg.ranges[1]: a number (float32) is required"),
    ("builtin_interfaces/msg/Time", {"sec": 2**31}, "msg.sec: 2147483648 is out of the range of int32"),
    ("builtin_interfaces/msg/Time", {"nanosec": -1}, "msg.nanosec: -1 is out of the range of uint32"),
    ("builtin_interfaces/msg/Time", {"sec": 1.5}, "msg.sec: a whole number (int32) is required"),
    ("std_msgs/msg/String", {"data": 5}, "msg.data: text is required, not a number"),
    ("nav_msgs/msg/Odometry", {"pose": {"covariance": [0.0] * 35}}, "msg.pose.covariance: exactly 36 values"),
    ("sensor_msgs/msg/CompressedImage", {"data": "not base64!"}, "msg.data: uint8[] text must be base64"),
    ("sensor_msgs/msg/CompressedImage", {"data": [1, 256]}, "msg.data[1]: 256 is out of the range of uint8"),
    ("sensor_msgs/msg/CompressedImage", {"data": 3}, "msg.data: uint8[] must be base64 text or an array of bytes"),
])
def test_a_message_that_does_not_fit_its_type_is_refused_with_the_fields_path(type_name, msg, reason):
    with pytest.raises(MessageError) as refused:
        conform(type_name, msg, STAMP)
    assert reason in str(refused.value)


def test_null_in_a_float_array_is_rosbridges_inf_or_nan_and_is_kept():
    scan = conform("sensor_msgs/msg/LaserScan", {"ranges": [1.0, None], "range_max": 12}, STAMP)
    assert scan["ranges"] == [1.0, None] and scan["range_max"] == 12


def test_bytes_come_as_base64_or_as_a_list():
    assert conform("sensor_msgs/msg/CompressedImage", {"data": "/wA="}, STAMP)["data"] == "/wA="
    assert conform("sensor_msgs/msg/CompressedImage", {"data": [255, 0]}, STAMP)["data"] == [255, 0]


def test_typedefs_have_rosapis_shape_and_order():
    """``rosapi`` (objectutils.py) lists the type, then each type it holds once, depth first."""
    found = typedefs("nav_msgs/msg/Odometry")
    assert [t["type"] for t in found] == [
        "nav_msgs/msg/Odometry", "std_msgs/msg/Header", "builtin_interfaces/msg/Time",
        "geometry_msgs/msg/PoseWithCovariance", "geometry_msgs/msg/Pose", "geometry_msgs/msg/Point",
        "geometry_msgs/msg/Quaternion", "geometry_msgs/msg/TwistWithCovariance", "geometry_msgs/msg/Twist",
        "geometry_msgs/msg/Vector3"]
    scan = typedefs("sensor_msgs/msg/LaserScan")[0]
    assert set(scan) == {"type", "fieldnames", "fieldtypes", "fieldarraylen", "examples", "constnames", "constvalues"}
    ranges = scan["fieldnames"].index("ranges")
    assert (scan["fieldtypes"][ranges], scan["fieldarraylen"][ranges], scan["examples"][ranges]) == \
        ("float32", 0, "[]")
    assert scan["examples"][scan["fieldnames"].index("range_min")] == "0.0"
    assert typedefs("custom_msgs/msg/Unknown") == []


@pytest.mark.parametrize("type_name", sorted(MESSAGE_TYPES))
def test_every_known_type_accepts_its_own_defaults(type_name):
    filled = conform(type_name, {}, STAMP)
    assert conform(type_name, filled, STAMP) == filled
