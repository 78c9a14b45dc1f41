"""The policy file: the shipped one for ros-mcp 3.x, and errors that name the file, the line and the key."""

from __future__ import annotations

import pytest

from safeembodai_core.guard_mcp.policy import PolicyError, parse_policy, read_policy

#: ros-mcp 3.1.2's tools as it lists them (tools/list over stdio), with the ones its annotations call destructive
ROS_MCP_TOOLS = ["get_actions", "get_action_details", "get_action_status", "send_action_goal", "cancel_action_goal",
                 "connect_to_robot", "ping_robots", "get_verified_robot_spec", "get_verified_robots_list",
                 "detect_ros_version", "view_saved_image", "get_nodes", "get_node_details", "get_parameter",
                 "set_parameter", "has_parameter", "delete_parameter", "get_parameters", "get_parameter_details",
                 "get_services", "get_service_type", "get_service_details", "call_service", "get_topics",
                 "get_topic_type", "get_topic_details", "get_message_details", "subscribe_once",
                 "subscribe_for_duration", "publish_for_durations", "publish_once"]
DESTRUCTIVE = {"send_action_goal", "cancel_action_goal", "set_parameter", "delete_parameter", "call_service",
               "publish_for_durations", "publish_once"}


def test_the_shipped_policy_maps_every_ros_mcp_tool_and_no_destructive_one_as_read_only():
    policy = read_policy()
    assert set(policy.tools) == set(ROS_MCP_TOOLS)
    assert not [tool for tool in DESTRUCTIVE if policy.tools[tool] == "read_only"]
    assert policy.mode == "refuse" and list(policy.velocity_topics) == ["/cmd_vel"]
    assert policy.allow.topics == {} and policy.allow.actions == [] and policy.allow.parameters == []
    assert all(service.startswith("/rosapi/") for service in policy.allow.services)


def test_a_velocity_topic_takes_either_ros_spelling_and_answers_in_the_policys():
    policy = parse_policy("velocity_topics:\n  /cmd_vel: [geometry_msgs/Twist]\n")
    assert policy.velocity_type("/cmd_vel", "geometry_msgs/msg/Twist") == "geometry_msgs/Twist"
    assert policy.velocity_type("/cmd_vel", "geometry_msgs/msg/TwistStamped") is None
    assert policy.velocity_type("/cmd_vel", "geometry_msgs/msg/Twist ") is None


@pytest.mark.parametrize("text, expected", [
    ("mod: limit\n", r"<p>:1: mod: Extra inputs are not permitted; did you mean 'mode'\?"),
    ("mode: fast\n", r"<p>:1: mode: Input should be 'refuse' or 'limit'"),
    ("horizon_s: true\n", r"<p>:1: horizon_s: Input should be a valid number, got True"),
    ("horizon_s: .nan\n", r"<p>:1: horizon_s: Input should be a finite number"),
    ("velocity_topics:\n  /cmd_vel/: [geometry_msgs/msg/Twist]\n", r"<p>:2: velocity_topics./cmd_vel/: a topic"),
    ("velocity_topics:\n  /cmd_vel: [std_msgs/msg/String]\n", r"cannot be judged"),
    ("velocity_topics:\n  /cmd_vel: []\n", r"list the types it takes"),
    ("allow:\n  topics:\n    /cmd_vel: [geometry_msgs/msg/Twist]\n", r"either judged .* or allowed unjudged"),
    ("allow:\n  services: [rosapi/topics]\n", r"<p>:2: allow.services.0: String should match pattern"),
    ("tools:\n  publish_once: read_write\n", r"<p>:2: tools.publish_once: Input should be 'read_only'"),
    ("failures: {threshold: 0}\n", r"failures.threshold: Input should be greater than or equal to 1"),
    ("mode: refuse\nmode: limit\n", r"<p>:2: mode: key repeated \(first on line 1\)"),
    ("- mode\n", r"a guard-mcp policy must be a YAML mapping"),
])
def test_a_bad_policy_names_the_line_and_the_key(text, expected):
    with pytest.raises(PolicyError, match=expected):
        parse_policy(text, "<p>")


def test_a_missing_policy_file_is_said_plainly(tmp_path):
    with pytest.raises(PolicyError, match="no such policy file"):
        read_policy(tmp_path / "nowhere.yaml")
    folder = tmp_path / "folder.yaml"
    folder.mkdir()
    with pytest.raises(PolicyError, match="cannot read the policy file"):
        read_policy(folder)


def test_what_the_agent_is_told_is_on_by_default_and_each_part_may_be_turned_off():
    shipped = read_policy()
    assert shipped.prefix_variant == "paper" and shipped.mark_untrusted and shipped.state_management
    chosen = parse_policy("security_prefix: release\nmark_untrusted: false\nstate_management: false\n")
    assert chosen.prefix_variant == "release" and not chosen.mark_untrusted and not chosen.state_management
    assert parse_policy("security_prefix: false\n").prefix_variant is None


@pytest.mark.parametrize("text", ["security_prefix: ../paper\n", "security_prefix: 1\n", "mark_untrusted: 1\n"])
def test_a_prefix_that_names_no_variant_or_a_flag_that_is_no_bool_is_an_error(text):
    with pytest.raises(PolicyError, match="<p>:1: (security_prefix|mark_untrusted)"):
        parse_policy(text, "<p>")
