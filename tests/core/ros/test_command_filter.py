"""The live guard node's loop (``CommandFilter``) on a recorded stream, and Nav2's source timeout."""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from safeembodai_core import Guard, RobotSpec, SlowdownZone
from safeembodai_core.ros import CommandFilter, LaserScan, Twist


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
