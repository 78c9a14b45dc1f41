"""``sensor_msgs/LaserScan`` into the guard (issue 23, part 1): ROS semantics for inf, -inf, NaN
and the range limits; any field of view and increment; the sensor's mounting; directions outside
the field of view unknown, never free; clear errors for scans that cannot be read.

The property: a scan from a scanner at the robot's centre, whose beams line up with the native
grid, gives the native scan itself, so every verdict through the adapter equals the verdict on
the native scan; from a mounted scanner, every return keeps (at most) its distance from the
robot's centre in its bearing's bin, so no obstacle the sensor saw is lost.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from safeembodai_core import Guard
from safeembodai_core.models import LidarScan
from safeembodai_core.ros import LaserScan, SensorMount

DEG = math.pi / 180.0


def ros_from_native(native_mm: np.ndarray, shift: int) -> LaserScan:
    """The native scan as a ROS scan of a centred scanner whose first beam is native beam
    ``shift`` (angle_min = shift * increment, wrapped to (-pi, pi])."""
    n = native_mm.size
    step = 2.0 * math.pi / n
    start = shift * step
    start = start - 2.0 * math.pi if start > math.pi else start
    return LaserScan(angle_min=start, angle_increment=step, ranges=np.roll(native_mm, -shift) / 1000.0,
                     range_min=0.0, range_max=8.0)


# ranges a message in metres carries exactly (mm / 1000 * 1000 gives them back): a range of 170 mm
# is 170.00000000000003 through metres, which a rule's boundary at 170 mm tells apart
carried_mm = st.floats(min_value=50.0, max_value=7999.0).map(lambda mm: mm / 1000.0 * 1000.0)
native_scans = st.integers(min_value=8, max_value=720).flatmap(
    lambda n: st.lists(st.one_of(carried_mm, st.just(math.inf), st.just(math.nan)), min_size=n, max_size=n))
plans = st.lists(st.one_of(
    st.builds(lambda d, back: {"command": "straight", "direction": "backward" if back else "forward", "distance": d},
              st.floats(min_value=1.0, max_value=399.0), st.booleans()),
    st.builds(lambda a, left: {"command": "turn", "direction": "left" if left else "right", "angle": a},
              st.floats(min_value=1.0, max_value=89.0), st.booleans())), min_size=1, max_size=4)


@settings(max_examples=150, deadline=None)
@given(native_scans, st.integers(min_value=0, max_value=719), plans)
@pytest.mark.slow
def test_a_centred_aligned_scan_is_the_native_scan_and_gets_the_same_verdicts(ranges, shift, plan):
    native = np.array(ranges, dtype=float)
    ros = ros_from_native(native, shift % native.size)
    converted = ros.to_lidar_scan()
    assert converted.beam_count == native.size
    np.testing.assert_array_equal(np.isnan(converted.ranges_mm), np.isnan(native))
    np.testing.assert_array_equal(converted.ranges_mm[~np.isnan(native)], native[~np.isnan(native)])  # exactly
    guard = Guard(["command_limits", "lidar_clearance", "footprint_sweep"])
    through_ros = guard.check(plan, lidar_mm=ros)
    direct = guard.check(plan, lidar_mm=LidarScan(native, 8000.0))
    assert [(v.rule, v.valid, v.signal_index) for v in through_ros.verdicts] == \
        [(v.rule, v.valid, v.signal_index) for v in direct.verdicts]


@settings(max_examples=100, deadline=None)
@given(st.floats(-300, 300), st.floats(-300, 300), st.floats(-180, 180),
       st.lists(st.floats(min_value=0.3, max_value=7.5), min_size=90, max_size=90))
def test_a_mounted_scanner_loses_no_return_it_saw(x_mm, y_mm, yaw_deg, ranges):
    """Every return, moved into the robot frame, lies in its bearing's bin no nearer than the bin says."""
    ros = LaserScan(angle_min=-math.pi, angle_increment=4 * DEG, ranges=ranges, range_min=0.1, range_max=8.0,
                    mount=SensorMount(x_mm, y_mm, yaw_deg))
    converted = ros.to_lidar_scan()
    angles = -math.pi + np.arange(90) * 4 * DEG + math.radians(yaw_deg)
    x = x_mm + np.array(ranges) * 1000 * np.cos(angles)
    y = y_mm + np.array(ranges) * 1000 * np.sin(angles)
    bins = np.rint(np.arctan2(y, x) / (2 * math.pi / converted.beam_count)).astype(int) % converted.beam_count
    assert np.all(converted.ranges_mm[bins] <= np.hypot(x, y) + 1e-6)


def scan_270(ranges_m: float | list[float], mount: SensorMount = SensorMount()) -> LaserScan:
    """A 270-degree scanner, 0.25-degree steps (1081 beams), as many ROS 2 drivers send it."""
    count = 1081
    ranges = [ranges_m] * count if not isinstance(ranges_m, list) else ranges_m
    return LaserScan(angle_min=-135 * DEG, angle_max=135 * DEG, angle_increment=0.25 * DEG, ranges=ranges,
                     range_min=0.05, range_max=10.0, mount=mount)


def test_outside_the_field_of_view_is_unknown_never_free():
    converted = scan_270(math.inf).to_lidar_scan()  # free all round the 270 degrees it sees
    angles = converted.angles_deg
    assert np.isposinf(converted.ranges_mm[np.abs(angles) <= 134]).all()
    assert np.isnan(converted.ranges_mm[np.abs(angles) >= 136]).all()
    guard = Guard(["lidar_clearance"])
    ahead = guard.check([{"command": "straight", "direction": "forward", "distance": 300}], lidar_mm=scan_270(math.inf))
    behind = guard.check([{"command": "straight", "direction": "backward", "distance": 300}],
                         lidar_mm=scan_270(math.inf))
    assert ahead.valid and not behind.valid
    assert "no LiDAR reading" in behind.reasons[0]


def test_ros_semantics_of_inf_nan_and_the_range_limits():
    ranges = [math.inf, math.nan, 0.01, -math.inf, 12.0, 1.5]
    ros = LaserScan(angle_min=0.0, angle_increment=60 * DEG, ranges=ranges, range_min=0.05, range_max=10.0)
    converted = ros.to_lidar_scan()
    assert converted.beam_count == 6
    # no return; no reading; below range_min: no reading; too close to measure: an obstacle at the
    # sensor; beyond range_max: no return; a return
    assert np.isposinf(converted.ranges_mm[0]) and np.isnan(converted.ranges_mm[1]) and np.isnan(converted.ranges_mm[2])
    assert converted.ranges_mm[3] == 0.0 and np.isposinf(converted.ranges_mm[4]) and converted.ranges_mm[5] == 1500.0
    assert converted.max_range_mm == 10_000.0


def test_the_mounting_moves_the_returns_to_the_robots_centre():
    """A scanner 200 mm ahead of the centre, turned to face backwards, sees a wall 0.5 m away: the
    wall is 300 mm behind the centre, and a backward straight of 200 mm is refused where one of
    50 mm passes (lidar_clearance's default 250 mm is measured from the body)."""
    mount = SensorMount(x_mm=200.0, y_mm=0.0, yaw_deg=180.0)
    converted = scan_270(0.5, mount).to_lidar_scan()
    behind = converted.sector(180.0, 1.0)
    assert abs(np.nanmin(converted.ranges_mm[behind]) - 300.0) < 1.0
    guard = Guard(["lidar_clearance"])
    far = guard.check([{"command": "straight", "direction": "backward", "distance": 200}],
                      lidar_mm=scan_270(0.5, mount))
    assert not far.valid
    assert np.isnan(converted.ranges_mm[converted.sector(0.0, 20.0)]).all()  # it cannot see ahead: unknown


def test_from_ros_reads_a_decoded_message_and_names_what_is_missing():
    message = SimpleNamespace(angle_min=-math.pi, angle_max=math.pi, angle_increment=DEG, time_increment=0.0,
                              scan_time=0.1, range_min=0.1, range_max=12.0, ranges=np.full(360, 3.0, dtype=np.float32),
                              intensities=np.zeros(0, dtype=np.float32))
    scan = LaserScan.from_ros(message, SensorMount(x_mm=100.0))
    assert scan.mount.x_mm == 100.0 and scan.angle_max == math.pi and scan.ranges.size == 360
    with pytest.raises(ValueError, match="not a sensor_msgs/LaserScan: no angle_increment, ranges"):
        LaserScan.from_ros(SimpleNamespace(angle_min=0.0, range_min=0.1, range_max=1.0))


@pytest.mark.parametrize("fields, message", [
    ({"ranges": []}, "at least one beam"),
    ({"angle_increment": math.nan}, "angle_increment must be finite"),
    ({"angle_increment": 0.0}, "angle_increment must be between"),
    ({"angle_increment": 1e-310}, "angle_increment must be between"),
    ({"angle_increment": 7.0}, "angle_increment must be between"),
    ({"range_min": 5.0, "range_max": 1.0}, "range_min < range_max"),
    ({"range_max": 1e307}, "range_max must be at most"),
    ({"ranges": ["a", "b"]}, "sequence of numbers"),
    ({"angle_min": "left"}, "angle_min must be a number"),
])
def test_a_scan_that_cannot_be_read_is_a_clear_error(fields, message):
    base = {"angle_min": 0.0, "angle_increment": DEG, "ranges": [1.0] * 360, "range_min": 0.1, "range_max": 10.0}
    with pytest.raises(ValueError, match=message):
        LaserScan(**{**base, **fields})
    with pytest.raises(ValueError, match="SensorMount.x_mm must be finite"):
        SensorMount(x_mm=math.inf)
