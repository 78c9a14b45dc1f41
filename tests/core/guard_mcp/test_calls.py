"""An agent's tool call read strictly: name variants, types, hostile values, unmapped actuation, retargeting."""

from __future__ import annotations

import math

import pytest

from safeembodai_core.guard_mcp.calls import CallRefused, Forward, Motion, read_call
from safeembodai_core.guard_mcp.policy import Allow, read_policy

ROBOT = ("127.0.0.1", 9090)
TWIST = "geometry_msgs/msg/Twist"
POLICY = read_policy()


def go(x=0.2, z=0.0):
    return {"linear": {"x": x, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": z}}


def once(topic="/cmd_vel", msg_type=TWIST, msg=None, policy=POLICY, **options):
    return read_call("publish_once", {"topic": topic, "msg_type": msg_type, "msg": go() if msg is None else msg},
                     policy, ROBOT, **options)


def refused(call, *args, match=None, **kwargs):
    with pytest.raises(CallRefused, match=match) as caught:
        call(*args, **kwargs)
    return caught.value


@pytest.mark.parametrize("topic", ["/cmd_vel", "cmd_vel"])
def test_the_guarded_topic_by_either_of_its_ros_names_is_judged_under_its_full_name(topic):
    motion = once(topic)
    assert isinstance(motion, Motion) and motion.topic == "/cmd_vel"
    assert motion.holds[0].twist.linear_x == 0.2 and motion.holds[0].duration_s == 0.0


@pytest.mark.parametrize("topic", ["/cmd_vel/", "//cmd_vel", "~/cmd_vel", " /cmd_vel", "/cmd vel", "", 7])
def test_a_name_ros_would_not_accept_is_refused(topic):
    assert "not a valid ROS name" in refused(once, topic).reason or "must be a string" in refused(once, topic).reason


@pytest.mark.parametrize("topic", ["/CMD_VEL", "/robot1/cmd_vel", "/cmd_vel_in", "/cmd_vel/raw"])
def test_another_topic_ros_would_accept_is_unlisted_so_refused(topic):
    assert "is not in the policy" in refused(once, topic).reason


def test_a_namespaced_velocity_topic_is_judged_once_the_policy_lists_it():
    policy = POLICY.model_copy(update={"velocity_topics": {"/robot1/cmd_vel": [TWIST]}})
    assert isinstance(once("robot1/cmd_vel", policy=policy), Motion)
    refused(once, "/cmd_vel", policy=policy, match="is not in the policy")


@pytest.mark.parametrize("msg_type", ["geometry_msgs/Twist", "geometry_msgs/msg/Twist"])
def test_either_ros_spelling_of_twist_is_judged_and_sent_in_the_policys(msg_type):
    assert once(msg_type=msg_type).msg_type == TWIST


def test_a_twist_stamped_is_judged_and_keeps_its_header():
    header = {"stamp": {"sec": 3, "nanosec": 5}, "frame_id": "base_link"}
    motion = once(msg_type="geometry_msgs/TwistStamped", msg={"header": header, "twist": go(0.1, 0.2)})
    assert motion.msg_type == "geometry_msgs/msg/TwistStamped"
    assert motion.holds[0].message == {"header": header, "twist": go(0.1, 0.2)}
    assert motion.holds[0].twist.angular_z == 0.2


@pytest.mark.parametrize("msg_type, msg", [
    ("geometry_msgs/msg/Accel", go()), ("std_msgs/msg/String", {"data": "go"}), ("geometry_msgs/msg/twist", go()),
    ("geometry_msgs/msg/Twist ", go()), ("Twist", go()), (None, go()),
    (TWIST, {"header": {}, "twist": go()}),  # stamped content under the plain type
    ("geometry_msgs/msg/TwistStamped", go()),  # plain content under the stamped type
    ("geometry_msgs/msg/TwistStamped", {"header": {"frame_id": 5}, "twist": go()}),
    ("geometry_msgs/msg/TwistStamped", {"header": {"seq": 1}, "twist": go()}),
])
def test_an_unknown_type_or_a_message_not_of_its_type_on_a_guarded_topic_is_refused(msg_type, msg):
    refused(once, msg_type=msg_type, msg=msg)


@pytest.mark.parametrize("value", [math.nan, math.inf, -math.inf, 10**400, "0.2", True, None, [0.2], {"x": 1}])
def test_a_value_that_is_no_finite_number_is_refused(value):
    message = go()
    message["linear"]["x"] = value
    reason = refused(once, msg=message).reason
    assert "msg:" in reason and "linear.x" in reason


@pytest.mark.parametrize("message", [
    {"linear": {"x": 0.2}},  # rosbridge would fill the zeros: guard-mcp asks for every field
    {"linear": {"x": 0.2, "y": 0.0, "z": 0.0}},
    {**go(), "extra": 1},
    {"linear": {"x": 0.2, "y": 0.0, "z": 0.0, "w": 1.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
    {"linear": {"x": 0.2, "y": 0.0, "z": 0.5}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
    {"linear": {"x": 0.2, "y": 0.3, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}},
    {"linear": {"x": 0.0, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.4, "z": 0.0}},
    "go", [], 0.2,
])
def test_a_missing_extra_or_unplanar_field_is_refused_with_the_full_form_as_advice(message):
    found = refused(once, msg=message)
    assert "linear" in found.advice or "planar" in found.reason or "sideways" in found.reason, found


def test_a_sideways_command_is_read_for_a_holonomic_base():
    message = {"linear": {"x": 0.0, "y": 0.3, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
    assert once(msg=message, holonomic=True).holds[0].twist.linear_y == 0.3


def durations(messages, seconds, rate_hz=0, policy=POLICY):
    return read_call("publish_for_durations", {"topic": "/cmd_vel", "msg_type": TWIST, "messages": messages,
                                                "durations": seconds, "rate_hz": rate_hz}, policy, ROBOT)


def test_a_sequence_is_read_as_its_holds():
    motion = durations([go(0.2), go(0.0)], [1.5, 0])
    assert [(h.twist.linear_x, h.duration_s) for h in motion.holds] == [(0.2, 1.5), (0.0, 0.0)]
    assert not motion.is_stop and durations([go(0.0)], [1]).is_stop


@pytest.mark.parametrize("seconds, rate, match", [
    ([-1.0], 0, "durations"), ([math.nan], 0, "durations"), (["1"], 0, "durations"), ([1.0, 2.0], 0, "same length"),
    ([31.0], 0, "durations"), ([20.0], 0, "motion lasts|same length"), ([1.0], 1000, "rate_hz"),
    ([1.0], math.inf, "rate_hz"),
])
def test_bad_durations_or_rates_are_refused(seconds, rate, match):
    messages = [go()] * (2 if match.startswith("motion") else 1)
    refused(durations, messages, seconds * len(messages) if match.startswith("motion") else seconds, rate,
            match=match)


def test_too_many_messages_are_refused():
    refused(durations, [go()] * 101, [0.1] * 101, match="at most 100")


ALLOWING = POLICY.model_copy(update={"allow": Allow(
    topics={"/led": ["std_msgs/msg/String"]}, services=["/dock"], actions=["/navigate"],
    parameters=["/base:max_speed"])})


@pytest.mark.parametrize("tool, arguments", [
    ("call_service", {"service_name": "/dock", "service_type": "std_srvs/srv/Trigger", "request": {}}),
    ("set_parameter", {"name": "/base:max_speed", "value": "9"}),
    ("delete_parameter", {"name": "/base:max_speed"}),
    ("send_action_goal", {"action_name": "/navigate", "action_type": "nav2_msgs/action/NavigateToPose", "goal": {}}),
    ("cancel_action_goal", {"action_name": "/navigate", "goal_id": "g1"}),
    ("publish_once", {"topic": "/led", "msg_type": "std_msgs/String", "msg": {"data": "on"}}),
])
def test_unmapped_actuation_is_refused_by_default_and_forwarded_once_allowed(tool, arguments):
    assert "allowlist" in refused(read_call, tool, arguments, POLICY, ROBOT).reason or "not in the policy" in \
        refused(read_call, tool, arguments, POLICY, ROBOT).reason
    forwarded = read_call(tool, arguments, ALLOWING, ROBOT)
    assert isinstance(forwarded, Forward) and forwarded.actuates


def test_an_allowed_call_is_forwarded_in_its_canonical_form():
    forwarded = read_call("call_service", {"service_name": "dock", "service_type": "std_srvs/Trigger",
                                           "request": {}, "timeout": 3}, ALLOWING, ROBOT)
    assert forwarded.arguments == {"service_name": "/dock", "service_type": "std_srvs/Trigger", "request": {},
                                   "timeout": 3.0}
    led = read_call("publish_once", {"topic": "led", "msg_type": "std_msgs/String", "msg": {"data": "on"}},
                    ALLOWING, ROBOT)
    assert led.arguments == {"topic": "/led", "msg_type": "std_msgs/msg/String", "msg": {"data": "on"}}
    refused(read_call, "publish_once", {"topic": "/led", "msg_type": "std_msgs/msg/Int8", "msg": {"data": 1}},
            ALLOWING, ROBOT, match="not in the policy")


@pytest.mark.parametrize("tool, arguments, match", [
    ("reboot_robot", {}, "maps no such tool"),
    ("publish_once", {"topic": "/cmd_vel", "msg_type": TWIST, "msg": go(), "latch": True}, "unknown argument"),
    ("publish_once", {"topic": "/cmd_vel", "msg_type": TWIST}, "no msg"),
    ("publish_once", ["/cmd_vel"], "must be an object"),
    ("set_parameter", {"name": "/base:max_speed"}, "no value"),
])
def test_an_unknown_tool_or_argument_is_refused(tool, arguments, match):
    refused(read_call, tool, arguments, ALLOWING, ROBOT, match=match)


@pytest.mark.parametrize("arguments", [{}, {"ip": "127.0.0.1", "port": 9090}, {"ip": " 127.0.0.1 ", "port": "9090"},
                                       {"ip": "127.0.0.1", "port": 9090, "ping_timeout": 1}])
def test_connect_to_robot_towards_the_configured_robot_is_forwarded_canonical(arguments):
    forwarded = read_call("connect_to_robot", arguments, POLICY, ROBOT)
    assert {key: forwarded.arguments[key] for key in ("ip", "port")} == {"ip": "127.0.0.1", "port": 9090}


@pytest.mark.parametrize("tool, arguments", [
    ("connect_to_robot", {"ip": "10.0.0.7", "port": 9090}), ("connect_to_robot", {"ip": "127.0.0.1", "port": 9091}),
    ("connect_to_robot", {"ip": "localhost"}), ("connect_to_robot", {"ip": "127.0.0.1", "port": True}),
    ("connect_to_robot", {"ip": "127.0.0.1", "ping_timeout": 1e9}),
    ("ping_robots", {"targets": [{"ip": "127.0.0.1", "port": 9090}, {"ip": "192.168.1.1", "port": 22}]}),
    ("ping_robots", {"targets": [{"ip": "127.0.0.1", "port": 9090, "via": "x"}]}),
    ("ping_robots", {"targets": [{"ip": "127.0.0.1", "port": 9090}] * 17}),
])
def test_another_robot_or_a_network_scan_is_refused(tool, arguments):
    refused(read_call, tool, arguments, POLICY, ROBOT)


def test_ping_robots_of_the_configured_robot_alone_is_forwarded():
    assert read_call("ping_robots", {}, POLICY, ROBOT).arguments == {"targets": [{"ip": "127.0.0.1", "port": 9090}]}
    refused(read_call, "ping_robots", {}, POLICY, ("10.0.0.2", 9090), match="only the configured robot")
