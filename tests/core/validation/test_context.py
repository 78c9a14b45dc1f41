"""Plans are judged from the planned pose; the Guard library API validates without a simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_core import Guard
from safeembodai_core.models import LidarScan, Straight, Turn
from safeembodai_core.testing import answer, straight, turn
from safeembodai_core.validation.context import ValidationContext


def scan_with(ranges: dict[int, float], default: float = np.inf, beams: int = 360) -> LidarScan:
    values = np.full(beams, default)
    for index, value in ranges.items():
        values[index] = value
    return LidarScan(values, max_range_mm=8000)


def test_context_at_the_scan_pose_returns_the_scan_itself():
    scan = scan_with({0: 1000, 90: 500})
    assert np.array_equal(ValidationContext(scan).ranges_at_pose(), scan.ranges_mm)


def test_turn_shifts_the_beams():
    scan = scan_with({90: 500})  # obstacle on the left
    ctx = ValidationContext(scan).advanced(Turn(command="turn", direction="left", angle=45)).advanced(
        Turn(command="turn", direction="left", angle=45))
    assert ctx.ranges_at_pose()[0] == 500  # now straight ahead
    half = ValidationContext(scan).advanced(Turn(command="turn", direction="left", angle=44.5))
    ranges = half.ranges_at_pose()
    assert ranges[45] == 500 or ranges[46] == 500  # between beams: the nearer neighbour is kept


def test_translation_reprojects_returns():
    scan = scan_with({0: 2000}, default=3000)
    ctx = ValidationContext(scan).advanced(Straight(command="straight", direction="forward", distance=300))
    assert ctx.ranges_at_pose()[0] == pytest.approx(1700, abs=1)
    back = ValidationContext(scan).advanced(Straight(command="straight", direction="backward", distance=300))
    assert back.ranges_at_pose()[0] == pytest.approx(2300, abs=1)


def test_missing_beams_stay_unknown_after_motion():
    values = np.full(360, 3000.0)
    values[0] = np.nan
    ctx = ValidationContext(LidarScan(values, 8000)).advanced(
        Straight(command="straight", direction="forward", distance=200))
    assert np.isnan(ctx.ranges_at_pose()[0])


def test_planned_offset_follows_turns_and_straights():
    ctx = ValidationContext(None)
    for signal in (Turn(command="turn", direction="left", angle=60), Turn(command="turn", direction="left", angle=30),
                   Straight(command="straight", direction="forward", distance=100)):
        ctx = ctx.advanced(signal)
    x, y, heading = ctx.offset
    assert heading == 90 and x == pytest.approx(0, abs=1e-9) and y == pytest.approx(100)


def test_lidar_scan_rejects_bad_shapes_and_negative_ranges():
    with pytest.raises(ValueError, match="1-D"):
        LidarScan(np.zeros((2, 3)), 1000)
    with pytest.raises(ValueError, match="negative"):
        LidarScan(np.array([1.0, -1.0, 2.0, 3.0]), 1000)
    with pytest.raises(ValueError, match="max_range_mm"):
        LidarScan(np.ones(8), math.inf)


def test_guard_checks_commands_against_a_scan_without_a_simulator():
    guard = Guard(["command_limits", "lidar_clearance"])  # the paper's rules
    wall_ahead = scan_with({k: 600 for k in range(-30, 31)}, default=5000)
    report = guard.check([straight(399)], lidar_mm=wall_ahead.ranges_mm, max_range_mm=8000)
    assert not report.valid and any("lidar_clearance" in r for r in report.reasons)
    assert guard.check([straight(300)], lidar_mm=wall_ahead.ranges_mm).valid
    assert guard.check([turn(80), straight(399)], lidar_mm=wall_ahead.ranges_mm).valid
    robot = Guard()  # the robot defaults: the 170 mm disc's sweep touches a wall at 500 mm after 330 mm
    nearer = scan_with({k: 500 for k in range(-30, 31)}, default=5000)
    assert robot.check([straight(329)], lidar_mm=nearer.ranges_mm, max_range_mm=8000).valid
    report = robot.check([straight(331)], lidar_mm=nearer.ranges_mm, max_range_mm=8000)
    assert not report.valid and "swept_body" in report.reasons[0] and "at most 329 mm is safe" in report.reasons[0]


def test_guard_reports_unparseable_commands_as_schema_failures():
    report = Guard().check([{"command": "straight", "direction": "forward", "distance": float("nan")}])
    assert not report.valid and report.verdicts[0].rule == "schema"
    raw = Guard().check_answer("move forward please")
    assert not raw.valid and "no JSON object" in raw.reasons[0]
    ok = Guard(rules=["command_limits"]).check_answer(answer(turn(30)))
    assert ok.valid and ok.response is not None


def test_guard_rule_without_a_scan_refuses_with_a_clear_reason():
    report = Guard(rules=["lidar_clearance"]).check([straight(100)])
    assert not report.valid and "needs a LiDAR scan" in report.reasons[0]


def test_translation_leaves_no_unknown_gap_where_the_sensor_measured():
    """A near object spreads out when seen from further on; the bins between its points are not unknown."""
    ranges = np.full(360, 3000.0)
    ranges[20:31] = 600.0
    moved = ValidationContext(LidarScan(ranges, 8000)).advanced(Straight(command="straight", direction="forward",
                                                                         distance=399))
    seen = moved.ranges_at_pose()
    assert not np.isnan(seen).any()
    assert seen[0] == pytest.approx(2601, abs=1)
    assert 600 < seen[25] < 1400  # the ray at 25 deg runs into the shadow edge behind the object's edge


def test_an_unread_beam_is_unknown_only_where_its_ray_comes_first():
    values = np.full(360, 3000.0)
    values[90] = np.nan  # unread to the left of the scan pose
    moved = ValidationContext(LidarScan(values, 8000)).advanced(
        Straight(command="straight", direction="forward", distance=300))
    seen = moved.ranges_at_pose()
    assert np.isnan(seen[135])  # from 300 mm on, looking back-left crosses that ray
    assert not np.isnan(seen[:80]).any()


def test_nearest_in_sector_at_the_scan_pose_and_after_moving():
    scan = scan_with({0: 1000, 20: 800, 45: 300, 90: np.nan}, default=np.inf)
    here = ValidationContext(scan).nearest_in_sector(0, 30)
    assert (here.distance_mm, here.bearing_deg, here.kind) == (800, 20, "return")
    turned = ValidationContext(scan, offset=(0.0, 0.0, 80.0)).nearest_in_sector(0, 30)
    assert (turned.distance_mm, turned.kind) == (0.0, "unread")  # the paper's rule: a nan beam refuses
    assert ValidationContext(scan).nearest_in_sector(180, 30).kind == "free_bound"
    moved = ValidationContext(scan).advanced(Straight(command="straight", direction="forward", distance=200))
    ahead = moved.nearest_in_sector(0, 30)  # the 800 mm return at 20 deg, now at 26 deg and 616 mm
    rad = math.radians(20)
    assert ahead.kind == "return" and ahead.distance_mm == pytest.approx(math.hypot(800 * math.cos(rad) - 200,
                                                                                    800 * math.sin(rad)))
