"""Plans are judged from the planned pose; the Guard library API validates without a simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_core import Guard
from safeembodai_core.models import LidarScan, Straight, Turn
from safeembodai_core.testing import answer, straight, turn
from safeembodai_core.validation import ValidationContext


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
    guard = Guard()
    wall_ahead = scan_with({k: 600 for k in range(-30, 31)}, default=5000)
    report = guard.check([straight(399)], lidar_mm=wall_ahead.ranges_mm, max_range_mm=8000)
    assert not report.valid and any("lidar_clearance" in r for r in report.reasons)
    assert guard.check([straight(300)], lidar_mm=wall_ahead.ranges_mm).valid
    assert guard.check([turn(80), straight(399)], lidar_mm=wall_ahead.ranges_mm).valid


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
