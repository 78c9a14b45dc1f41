"""``GuardNode``: rosbridge's messages in, what the base gets out; stops when the scan or the planner goes quiet."""

from __future__ import annotations

import json
import math

import pytest

from safeembodai_core import Guard
from safeembodai_core.guard_node.node import GuardNode, pose_of_odometry
from safeembodai_core.ros.robot_file import RobotFile


def scan_message(ranges):
    """A scan as rosbridge's JSON carries it: 360 beams, ``null`` where REP 117 says ``inf``."""
    message = {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "base_scan"}, "angle_min": 0.0,
               "angle_max": 2 * math.pi * 359 / 360, "angle_increment": 2 * math.pi / 360, "time_increment": 0.0,
               "scan_time": 0.1, "range_min": 0.02, "range_max": 6.0, "ranges": ranges, "intensities": []}
    return json.loads(json.dumps(message))


def twist(x=0.0, z=0.0):
    return {"linear": {"x": x, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": z}}


def node_for(null_range="no_return", **options):
    robot = RobotFile(radius_mm=170.0, scans={"/scan": {"null_range": null_range}},
                      velocity_smoother={"max_accel": [100.0, 0.0, 100.0], "max_decel": [-100.0, 0.0, -100.0]})
    return GuardNode(Guard(robot=robot.robot_spec()), robot, **options)


def test_an_open_room_as_rosbridge_sends_it_lets_a_command_through():
    node = node_for()
    node.on_scan(scan_message([None] * 360), 0.0)
    sent = node.on_command(twist(0.3), 0.01)
    assert sent.action == "forward" and sent.twist.linear_x == pytest.approx(0.3), sent.reasons


def test_a_wall_ahead_slows_then_stops_and_reversing_away_goes_out():
    node = node_for()
    ranges = [None] * 360
    ranges[0] = ranges[1] = ranges[359] = 0.30
    node.on_scan(scan_message(ranges), 0.0)
    ahead = node.on_command(twist(0.5), 0.01)
    assert ahead.action in ("limit", "stop") and ahead.twist.linear_x < 0.5
    ranges[0] = ranges[1] = ranges[359] = 0.171
    node.on_scan(scan_message(ranges), 0.02)
    touching = node.on_command(twist(0.5), 0.03)  # 1 mm left: Nav2's approach scaling leaves a crawl at most
    assert touching.action in ("limit", "stop") and touching.twist.linear_x < 0.005
    back = node.on_command(twist(-0.2), 0.04)
    assert back.twist.linear_x == pytest.approx(-0.2), back.reasons


def test_a_stale_scan_stops_the_robot_even_without_a_new_command():
    node = node_for(scan_timeout_s=0.5)
    node.on_scan(scan_message([None] * 360), 0.0)
    assert node.on_command(twist(0.3), 0.1).action == "forward"
    assert node.on_command(twist(0.3), 0.4).action == "forward"
    stale = node.cycle(0.55)  # the command is 0.15 s old, the scan 0.55 s
    assert stale is not None and stale.action == "stop" and "old" in stale.reasons[0]


def test_a_silent_planner_is_stopped_after_the_command_timeout_once():
    node = node_for()
    node.on_scan(scan_message([None] * 360), 0.0)
    node.on_command(twist(0.3), 0.0)
    for t in (0.1, 0.2, 0.3):
        node.on_scan(scan_message([None] * 360), t)
        assert node.cycle(t).twist.linear_x == pytest.approx(0.3)
    node.on_scan(scan_message([None] * 360), 0.55)
    stop = node.cycle(0.6)
    assert stop.action == "stop" and "no command" in stop.reasons[0]
    assert node.cycle(0.65) is None  # the base stands: nothing more to say


def test_null_ranges_read_as_unknown_refuse_motion_in_an_open_room():
    node = node_for(null_range="unknown")
    node.on_scan(scan_message([None] * 360), 0.0)
    assert node.on_command(twist(0.3), 0.01).twist.linear_x < 0.3


@pytest.mark.parametrize("bad", [
    {"linear": {"x": float("nan"), "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}},
    {"linear": {"x": 10 ** 400, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}},
    {"linear": {"x": "fast"}, "angular": {}},
    {"linear": {"x": True, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}},
    "not a twist", None, [], {"data": "drive"},
])
def test_a_bad_command_is_a_stop_with_its_reason_never_an_exception(bad):
    node = node_for()
    node.on_scan(scan_message([None] * 360), 0.0)
    node.on_command(twist(0.3), 0.0)
    sent = node.on_command(bad, 0.01)
    assert sent.action == "stop" and sent.twist.linear_x == 0.0 and sent.reasons
    assert node.unread["command"] == 1


def test_an_absurd_speed_is_bounded_by_the_smoother_before_the_guard_judges_it():
    node = node_for()
    node.on_scan(scan_message([None] * 360), 0.0)
    sent = node.on_command(twist(1.8e306, -1e300), 0.01)
    assert sent.action == "limit" and sent.twist.linear_x == pytest.approx(0.5)  # Nav2's default max_velocity
    assert sent.twist.angular_z == pytest.approx(-2.5) and "velocity smoother" in sent.reasons[0]


@pytest.mark.parametrize("bad", [{"ranges": [1.0]}, "junk", {**scan_message([None] * 360), "range_max": 10 ** 400},
                                 {**scan_message([None] * 360), "angle_increment": 0.0}])
def test_a_bad_scan_is_counted_and_the_last_good_one_ages_out(bad):
    node = node_for(scan_timeout_s=0.5)
    node.on_scan(scan_message([None] * 360), 0.0)
    node.on_scan(bad, 0.1)
    assert node.unread["scan"] == 1
    assert node.on_command(twist(0.3), 0.2).action == "forward"
    assert node.on_command(twist(0.3), 0.6).action == "stop"


def test_odometry_gives_the_pose_and_a_bad_one_is_ignored():
    half = math.radians(90.0) / 2
    message = {"pose": {"pose": {"position": {"x": 1.5, "y": -0.25, "z": 0.0},
                                 "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)}}}}
    x, y, heading = pose_of_odometry(message)
    assert (x, y, heading) == pytest.approx((1500.0, -250.0, 90.0))
    node = node_for()
    node.on_odom({"pose": {"pose": {"position": {"x": None}}}}, 0.0)
    node.on_odom({"pose": {"pose": {"position": {"x": 0, "y": 0, "z": 0},
                                    "orientation": {"x": 0, "y": 0, "z": 0, "w": 0}}}}, 0.0)
    assert node.unread["odom"] == 2


def test_a_planner_at_the_nodes_rate_is_judged_once_per_command_and_the_timer_still_catches_staleness():
    node = node_for(scan_timeout_s=0.5, period_s=0.05)
    t = 0.0
    for _ in range(20):  # commands and timer cycles at 20 Hz each, scans at 40 Hz
        node.on_scan(scan_message([None] * 360), t)
        node.on_command(twist(0.3), t)
        node.on_scan(scan_message([None] * 360), t + 0.025)
        assert node.cycle(t + 0.03) is None  # judged 30 ms ago: nothing new to say
        t += 0.05
    assert node.judgments == 20
    last_scan = t - 0.025
    assert node.on_command(twist(0.3), last_scan + 0.49).action == "forward"  # the scan still fresh
    stale = node.cycle(last_scan + 0.51)  # 20 ms after that judgment, but the scan has gone stale: a stop
    assert stale is not None and stale.action == "stop" and "old" in stale.reasons[0]
