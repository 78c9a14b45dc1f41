"""The live guard node's loop (``CommandFilter``) on a recorded stream, and Nav2's source timeout."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from safeembodai_core import Guard, RobotSpec, SlowdownZone
from safeembodai_core.ros import CommandFilter, LaserScan, Twist
from safeembodai_core.ros.laser_scan import SensorMount


def scan_msg(ranges_m, increment_deg=1.0):
    return SimpleNamespace(angle_min=0.0, angle_increment=math.radians(increment_deg), range_min=0.05, range_max=8.0,
                           ranges=list(ranges_m))


def wall_ahead(distance_m, beams=360):
    """A wall across the robot's path ``distance_m`` ahead (beams of 1 degree; behind it nothing)."""
    out = []
    for k in range(beams):
        c = math.cos(math.radians(k * 360.0 / beams))
        out.append(distance_m / c if c > 0.05 else math.inf)
    return out


def stream(scan_hz: float, cmd_hz: float, seconds: float, scan_until: float | None = None):
    """A recorded stream: (time, kind) events in time order, scans stopping at ``scan_until``."""
    events = [(k / scan_hz + 1e-3, "scan") for k in range(int(seconds * scan_hz))
              if scan_until is None or k / scan_hz < scan_until]
    events += [(k / cmd_hz, "cmd") for k in range(int(seconds * cmd_hz))]
    return sorted(events)


@pytest.mark.parametrize("scan_hz", [10.0, 40.0])
def test_a_recorded_stream_is_forwarded_slowed_and_stopped(scan_hz):
    """Driving at 0.3 m/s towards a wall that the scans bring nearer: forward while far, slowed
    within the horizon (Nav2's approach), and a stop when the scans stop coming (Nav2's source_timeout)."""
    node = CommandFilter(Guard(), horizon_s=1.0, scan_timeout_s=0.3)
    decisions = []
    for time_s, kind in stream(scan_hz, 20.0, 4.0, scan_until=3.0):
        if kind == "scan":
            node.on_scan(scan_msg(wall_ahead(1.5 - 0.4 * time_s)), time_s)  # 1.5 m, then nearer
        else:
            decisions.append(node.on_command(Twist(0.3, 0.0), time_s))
    actions = [d.action for d in decisions]
    assert actions[0] == "stop" and "no scan yet" in decisions[0].reasons[0]  # the first command beat the first scan
    assert "forward" in actions and "limit" in actions
    first_limit = actions.index("limit")
    assert all(a != "forward" for a in actions[first_limit:])  # once slowed, it never speeds up again here
    for d in decisions[first_limit:]:
        if d.action == "limit":
            assert 0.0 < d.twist.linear_x < 0.3 and d.collision_time_s is not None
            assert d.reasons[0].startswith("approach")
    late = [d for d in decisions if d.time_s > 3.0 + 0.3 + 1.0 / scan_hz]
    assert late and all(d.action == "stop" and "old" in d.reasons[0] for d in late)


def test_refuse_mode_stops_instead_of_slowing():
    node = CommandFilter(Guard(), horizon_s=1.0, mode="refuse")
    node.on_scan(scan_msg(wall_ahead(0.4)), 0.0)
    near = node.on_command(Twist(0.3, 0.0), 0.05)
    assert near.action == "stop" and near.twist == Twist(0.0, 0.0) and "swept_body" in " ".join(near.reasons)
    assert node.on_command(Twist(0.1, 0.0), 0.06).action == "forward"


def test_a_pose_that_moved_since_the_scan_is_judged_from_where_the_robot_is():
    """The scan was taken 0.9 m from the wall; the robot has since driven 0.5 m: 0.4 m left."""
    node = CommandFilter(Guard(), horizon_s=1.0, scan_timeout_s=1.0, mode="refuse")
    node.on_pose((0.0, 0.0, 0.0), 0.0)
    node.on_scan(scan_msg(wall_ahead(0.9)), 0.0)
    assert node.on_command(Twist(0.3, 0.0), 0.01).action == "forward"  # 0.9 - 0.17 = 0.73 m > 0.3 m
    node.on_pose((500.0, 0.0, 0.0), 0.5)
    moved = node.on_command(Twist(0.3, 0.0), 0.5)
    assert moved.action == "stop"


def test_slowdown_zones_and_bad_input():
    zone = SlowdownZone(0.5, band_mm=400.0, name="near")
    node = CommandFilter(Guard(), slowdown=[zone])
    node.on_scan(scan_msg([0.5] + [math.inf] * 359), 0.0)  # something 0.5 m ahead: within 400 mm of the body
    slowed = node.on_command(Twist(0.05, 0.0), 0.01)
    assert slowed.action == "limit" and slowed.twist.linear_x == pytest.approx(0.025) and "near" in slowed.reasons[0]
    sideways = node.on_command(Twist(0.0, 0.0, 0.2), 0.02)
    assert sideways.action == "stop" and "holonomic" in sideways.reasons[0]
    with pytest.raises(ValueError, match="angle_increment"):
        node.on_scan(scan_msg([1.0] * 4, increment_deg=math.nan), 0.03)
    assert node.on_command(Twist(0.05, 0.0), 0.04).scan_age_s == pytest.approx(0.04)  # the last good scan stays
    with pytest.raises(ValueError, match="horizon_s"):
        CommandFilter(Guard(), horizon_s=-1)
    with pytest.raises(ValueError, match="time_s"):
        node.on_command(Twist(0.1, 0.0), math.nan)
    early = node.on_command(Twist(0.1, 0.0), -1.0)
    assert early.action == "stop" and "before the latest scan" in early.reasons[0]


def test_a_holonomic_base_is_filtered_sideways_too():
    node = CommandFilter(Guard(robot=RobotSpec(holonomic=True)))
    left = [math.inf] * 360
    left[90] = 0.45  # 0.45 m to the left
    node.on_scan(LaserScan(angle_min=0.0, angle_increment=math.radians(1), ranges=left, range_min=0.05,
                           range_max=8.0), 0.0)
    d = node.on_command(Twist(0.0, 0.0, 0.5), 0.01)
    assert d.action == "limit" and 0 < d.twist.linear_y < 0.5 and d.twist.linear_x == 0.0
    assert d.collision_time_s == pytest.approx((450 - 170) / 500, abs=1e-6)


@pytest.mark.parametrize("at_m", [0.3, 0.2999], ids=["on the outline", "0.1 mm inside"])
@pytest.mark.parametrize("mode", ["limit", "refuse"])
def test_a_robot_on_a_return_is_let_back_off_it_but_not_on(at_m, mode):
    """A return on the 300 mm disc's outline (Nav2 counts it outside) or 0.1 mm inside it: reversing
    and a reversing arc go out as asked, driving on is a stop; a reverse towards a return behind is
    slowed (``limit``) or stopped (``refuse``) as any approach is."""
    ranges = [3.0] * 360
    ranges[0] = at_m
    node = CommandFilter(Guard(robot=RobotSpec(radius_mm=300)), mode=mode)
    node.on_scan(scan_msg(ranges), 0.0)
    for time_s, twist in ((0.01, Twist(-0.5, 0.0)), (0.02, Twist(-0.3, 0.8)), (0.03, Twist(0.0, 1.0))):
        out = node.on_command(twist, time_s)
        assert out.action == "forward" and out.twist == twist and not out.reasons
    for time_s, twist in ((0.04, Twist(0.5, 0.0)), (0.05, Twist(0.3, 0.8))):
        on = node.on_command(twist, time_s)
        assert on.action == "stop" and on.twist == Twist(0.0, 0.0) and on.collision_time_s == 0.0
    ranges[180] = 0.6
    node.on_scan(scan_msg(ranges), 0.1)
    back = node.on_command(Twist(-0.5, 0.0), 0.11)
    assert back.collision_time_s == pytest.approx(0.6)
    if mode == "limit":
        assert back.action == "limit" and back.twist.linear_x == pytest.approx(-0.3)
    else:
        assert back.action == "stop" and back.twist == Twist(0.0, 0.0)


@pytest.mark.parametrize("mode", ["limit", "refuse"])
@pytest.mark.parametrize("command, field", [
    (Twist(1.8e305, 0.0), "linear.x"),
    (Twist(-1.7e308, 0.5), "linear.x"),
    ({"linear": {"x": 1e306, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}}, "linear.x"),
    ((0.0, 0.0, 1.8e305), "linear.y"),
])
def test_a_command_too_fast_to_judge_is_a_stop_naming_its_field(mode, command, field):
    node = CommandFilter(Guard(robot=RobotSpec(holonomic=True)), mode=mode)
    node.on_scan(scan_msg([3.0] * 360), 0.0)
    decision = node.on_command(command, 0.01)
    assert decision.action == "stop" and decision.twist == Twist(0.0, 0.0)
    speed = decision.requested.linear_x if field == "linear.x" else decision.requested.linear_y
    assert decision.reasons == [f"command refused unjudged: Twist {field} = {speed:g} m/s is too fast to judge: in "
                                "millimetres per second it overflows"]


def test_a_hold_past_the_longest_arc_is_a_decision_not_an_error():
    node = CommandFilter(Guard(["lidar_clearance"]), horizon_s=60.0)
    node.on_scan(scan_msg([5.0] * 360), 0.0)
    assert node.on_command(Twist(2.1911947173421553, 0.0), 0.01).action in ("limit", "stop")


HUGE = 10**400


def scan_dict(**fields):
    message = {"angle_min": 0.0, "angle_increment": math.radians(1.0), "angle_max": math.radians(359.0),
               "range_min": 0.05, "range_max": 8.0, "ranges": [3.0] * 360, "time_increment": 0.0, "scan_time": 0.1}
    return {**message, **fields}


def twist_dict(vector, axis):
    message = {"linear": {"x": 0.1, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}
    message[vector][axis] = HUGE
    return message


def live_node():
    node = CommandFilter(Guard())
    node.on_scan(scan_dict(), 0.0)
    return node


SCAN_FIELDS = ["angle_min", "angle_increment", "angle_max", "range_min", "range_max", "time_increment", "scan_time"]
#: every number the guard reads, each given an integer too large for a float: (the field's name, the call)
HUGE_INPUTS = [
    *[(f"LaserScan.{name}", lambda name=name: live_node().on_scan(scan_dict(**{name: HUGE}), 0.01))
      for name in SCAN_FIELDS],
    (r"LaserScan.ranges\[7\]", lambda: live_node().on_scan(scan_dict(ranges=[3.0] * 7 + [HUGE] + [3.0] * 352), 0.01)),
    *[(f"SensorMount.{name}", lambda name=name: SensorMount(**{name: HUGE})) for name in ("x_mm", "y_mm", "yaw_deg")],
    *[(f"Twist.{name}", lambda name=name: Twist(**{"linear_x": 0.0, "angular_z": 0.0, name: HUGE}))
      for name in ("linear_x", "angular_z", "linear_y")],
    *[(f"CommandFilter.on_pose.{name}", lambda i=i: live_node().on_pose(tuple(HUGE if j == i else 0.0
                                                                              for j in range(3)), 0.01))
      for i, name in enumerate(("x_mm", "y_mm", "heading_deg"))],
    *[(f"CommandFilter.{method}.time_s", lambda method=method, args=args: getattr(live_node(), method)(*args, HUGE))
      for method, args in (("on_scan", (scan_dict(),)), ("on_pose", ((0.0, 0.0, 0.0),)),
                           ("on_command", (Twist(0.1, 0.0),)))],
    *[(f"CommandFilter.{name}", lambda name=name: CommandFilter(Guard(), **{name: HUGE}))
      for name in ("horizon_s", "scan_timeout_s")],
    ("SlowdownZone.factor", lambda: SlowdownZone(HUGE, band_mm=100.0)),
    ("SlowdownZone.band_mm", lambda: SlowdownZone(0.5, band_mm=HUGE)),
    ("SlowdownZone.polygon_mm", lambda: SlowdownZone(0.5, polygon_mm=((0, 0), (HUGE, 0), (0, 1)))),
    ("RobotSpec.footprint_mm", lambda: RobotSpec(footprint_mm=((0, 0), (HUGE, 0), (0, 1)))),
    ("radius_mm", lambda: RobotSpec(radius_mm=HUGE).body()),
    ("duration_s", lambda: Guard().check_twist((0.1, 0.0), HUGE, lidar_mm=[3000.0] * 360)),
    ("horizon_s", lambda: Guard().limit_twist((0.1, 0.0), HUGE, lidar_mm=[3000.0] * 360)),
    ("time_s", lambda: Guard().check_twist((0.1, 0.0), 1.0, lidar_mm=[3000.0] * 360, time_s=HUGE)),
    ("x_mm", lambda: Guard().check_twist((0.1, 0.0), 1.0, lidar_mm=[3000.0] * 360, pose=(HUGE, 0.0, 0.0))),
    ("heading_deg", lambda: Guard().check_twist((0.1, 0.0), 1.0, lidar_mm=[3000.0] * 360, since_scan=(0.0, 0.0, HUGE))),
]


@pytest.mark.parametrize("field, call", HUGE_INPUTS, ids=[field.replace("\\", "") for field, _ in HUGE_INPUTS])
def test_a_huge_integer_in_any_number_the_guard_reads_is_a_value_error_naming_it(field, call):
    """JSON and rosbridge carry integers of any size: not one reaches a float conversion unguarded."""
    with pytest.raises(ValueError, match=field):
        call()


@pytest.mark.parametrize("vector, axis", [(v, a) for v in ("linear", "angular") for a in "xyz"])
def test_a_huge_integer_in_a_command_is_a_stop_naming_its_field(vector, axis):
    decision = live_node().on_command(twist_dict(vector, axis), 0.01)
    assert decision.action == "stop" and f"Twist.{vector}.{axis} must be a number" in decision.reasons[0]
    for index in range(3):  # the tuple form
        command = tuple(HUGE if j == index else 0.0 for j in range(3))
        decision = CommandFilter(Guard(robot=RobotSpec(holonomic=True))).on_command(command, 0.01)
        assert decision.action == "stop" and "must be a number" in decision.reasons[0]


def test_a_late_older_scan_is_refused_and_the_newer_one_stays():
    """Issue 52 item 11: a free scan stamped 0.6 s arriving after a wall scan at 1.0 s must not turn the
    limited command into a forwarded one."""
    node = CommandFilter(Guard(), horizon_s=1.0, scan_timeout_s=0.5)
    node.on_scan(scan_msg(wall_ahead(0.8)), 1.0)
    assert node.on_command(Twist(0.8, 0.0), 1.05).action == "limit"
    with pytest.raises(ValueError, match=r"taken at 0\.6 s is older than the one held \(taken at 1\.0 s\)"):
        node.on_scan(scan_msg([math.inf] * 360), 0.6)
    assert node.latest_scan_time == 1.0 and node.on_command(Twist(0.8, 0.0), 1.06).action == "limit"
    node.on_scan(scan_msg([math.inf] * 360), 1.0)  # the same time again is not older: it replaces it
    assert node.on_command(Twist(0.8, 0.0), 1.07).action == "forward"


@pytest.mark.parametrize("mode", ["limit", "refuse"])
def test_poses_that_start_after_a_scan_taken_without_one_stop_until_a_new_scan(mode):
    """Issue 52 item 12: a scan taken before any pose cannot be placed once poses arrive (the robot may
    be anywhere relative to it): a stop, not the scan judged as if the robot had not moved."""
    node = CommandFilter(Guard(), horizon_s=1.0, scan_timeout_s=1.0, mode=mode)
    node.on_scan(scan_msg([math.inf] * 360), 0.0)
    assert node.on_command(Twist(0.2, 0.0), 0.05).action == "forward"  # no poses at all: the scan is where it is
    node.on_pose((0.0, 0.0, 0.0), 0.1)
    node.on_pose((1e6, 0.0, 0.0), 0.2)  # 1 km on
    lost = node.on_command(Twist(0.2, 0.0), 0.25)
    assert lost.action == "stop" and lost.twist == Twist(0.0, 0.0) and "before any pose" in lost.reasons[0]
    node.on_scan(scan_msg([math.inf] * 360), 0.3)  # taken where the robot now is
    assert node.on_command(Twist(0.2, 0.0), 0.35).action == "forward"
    node.on_pose((2e6, 0.0, 0.0), 0.4)  # another km on, after a scan placed by a pose: judged, and stopped
    assert node.on_command(Twist(0.2, 0.0), 0.45).action == "stop"


def test_with_a_pose_before_the_scan_the_same_jump_stops():
    node = CommandFilter(Guard(), horizon_s=1.0, scan_timeout_s=1.0)
    node.on_pose((0.0, 0.0, 0.0), 0.0)
    node.on_scan(scan_msg([math.inf] * 360), 0.0)
    node.on_pose((1e6, 0.0, 0.0), 0.2)
    assert node.on_command(Twist(0.2, 0.0), 0.25).action == "stop"


@pytest.mark.parametrize("pose", [b"abc", bytearray(b"abc"), "123", {1.0, 2.0, 3.0}, {"x": 0, "y": 0, "h": 0},
                                  iter((0.0, 0.0, 0.0)), (0.0, 0.0), (0.0, 0.0, 0.0, 0.0), ("1", "2", "3"),
                                  (True, 0.0, 0.0), (0.0, 0.0, [0.0]), 12.0, None])
def test_a_pose_is_a_sequence_of_exactly_three_numbers(pose):
    """Issue 52 item 14: bytes were read as (97, 98, 99), a set in whatever order it iterates."""
    node = live_node()
    with pytest.raises(ValueError, match="CommandFilter.on_pose"):
        node.on_pose(pose, 0.01)
    assert node._pose is None


def test_a_pose_may_be_a_tuple_a_list_or_an_array():
    import numpy as np

    for pose in ((1.0, 2.0, 3.0), [1, 2, 3], np.array([1.0, 2.0, 3.0])):
        node = live_node()
        node.on_pose(pose, 0.01)
        assert node._pose == (1.0, 2.0, 3.0)


@pytest.mark.parametrize("call", [lambda node: node.on_scan(scan_dict(), "0.1"),
                                  lambda node: node.on_pose((0.0, 0.0, 0.0), "0.1"),
                                  lambda node: node.on_command(Twist(0.1, 0.0), "0.1"),
                                  lambda node: node.on_command(Twist(0.1, 0.0), b"0.1")])
def test_a_time_as_text_is_no_time(call):
    with pytest.raises(ValueError, match="time_s must be a number of seconds"):
        call(live_node())


@pytest.mark.parametrize("command", [("1_0", 0.0), (0.1, "0"), (b"1", 0.0), (True, 0.0)])
def test_a_command_with_text_or_a_bool_for_a_number_is_a_stop(command):
    decision = live_node().on_command(command, 0.01)
    assert decision.action == "stop" and "must be a number" in decision.reasons[0]
