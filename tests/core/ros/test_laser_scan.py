"""``sensor_msgs/LaserScan`` into the guard (issue 23, part 1): ROS semantics for inf, -inf, NaN
and the range limits; any field of view and increment; the sensor's mounting; directions outside
the field of view unknown, never free; clear errors for scans that cannot be read. Scans as rosbridge
sends them (JSON, where ``inf``, ``-inf`` and ``nan`` are all ``null``), read as ``null_range`` says.

The property: a scan from a scanner at the robot's centre, whose beams line up with the native
grid, gives the native scan itself, so every verdict through the adapter equals the verdict on
the native scan; from a mounted scanner, every return keeps (at most) its distance from the
robot's centre in its bearing's bin, so no obstacle the sensor saw is lost.
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterable
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from safeembodai_core import Guard
from safeembodai_core.models import LidarScan
from safeembodai_core.ros import LaserScan, SensorMount, Twist
from safeembodai_core.ros.laser_scan import MountedScan

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
    ({"ranges": ["a", "b"]}, r"ranges\[0\] must be a number of metres, got 'a'"),
    ({"ranges": "3.0"}, "sequence of numbers"),
    ({"angle_min": "left"}, "angle_min must be a number"),
])
def test_a_scan_that_cannot_be_read_is_a_clear_error(fields, message):
    base = {"angle_min": 0.0, "angle_increment": DEG, "ranges": [1.0] * 360, "range_min": 0.1, "range_max": 10.0}
    with pytest.raises(ValueError, match=message):
        LaserScan(**{**base, **fields})
    with pytest.raises(ValueError, match="SensorMount.x_mm must be finite"):
        SensorMount(x_mm=math.inf)


# -- as rosbridge sends it ----------------------------------------------------------------------

#: a rosbridge v2 publish of a 360-beam ``sensor_msgs/msg/LaserScan`` (beam 180 straight ahead), as
#: rosbridge_server writes it; the ranges go in at %s
SCAN_FRAME = """{"op": "publish", "topic": "/scan", "msg": {
  "header": {"stamp": {"sec": 1718000000, "nanosec": 500000000}, "frame_id": "base_scan"},
  "angle_min": -3.141592653589793, "angle_max": 3.1241393089294434, "angle_increment": 0.017453292519943295,
  "time_increment": 0.0, "scan_time": 0.1, "range_min": 0.12, "range_max": 3.5,
  "ranges": [%s], "intensities": []}}"""


def rosbridge_scan(ranges: list[str]) -> dict:
    """The ``msg`` of :data:`SCAN_FRAME` with ``ranges`` (JSON text: ``"1.0"``, ``"null"``), parsed."""
    assert len(ranges) == 360
    return json.loads(SCAN_FRAME % ", ".join(ranges))["msg"]


def room(wall_m: str = "null", nulls: Iterable[int] = ()) -> dict:
    """A scan of walls ``wall_m`` away all round (``null``: an open room), ``null`` at the beams ``nulls``."""
    nulls = set(nulls)
    return rosbridge_scan(["null" if beam in nulls else wall_m for beam in range(360)])


def test_from_ros_reads_a_scan_as_rosbridge_sends_it():
    message = json.loads("""{"header": {"stamp": {"sec": 12, "nanosec": 0}, "frame_id": "laser"},
        "angle_min": -1.5707963705062866, "angle_max": 1.5707963705062866, "angle_increment": 1.5707963705062866,
        "time_increment": 0.0, "scan_time": null, "range_min": 0.1, "range_max": 8,
        "ranges": [2, null, 0.75], "intensities": [47.0, 0.0, 51.0]}""")
    unknown = LaserScan.from_ros(message, SensorMount(x_mm=100.0))
    assert list(unknown.ranges[[0, 2]]) == [2.0, 0.75] and math.isnan(unknown.ranges[1])
    assert unknown.range_max == 8.0 and unknown.angle_max == pytest.approx(math.pi / 2) and unknown.mount.x_mm == 100.0
    assert math.isnan(LaserScan.from_ros(message).ranges[1])  # unknown is the default
    assert LaserScan.from_ros(message, null_range="no_return").ranges[1] == math.inf
    assert message["ranges"][1] is None  # the message is left as it came


def test_an_open_room_of_nulls_is_free_with_no_return_and_unknown_by_default():
    """rosbridge writes the open directions' ``+inf`` as ``null``: read as no reading, nothing may move."""
    open_room = room()
    refused = Guard().check_twist(Twist(0.3, 0.0), 1.0, lidar_mm=LaserScan.from_ros(open_room))
    assert not refused.valid and refused.safe_duration_s < 0.05 and "unseen" in refused.contact
    for command in (Twist(0.3, 0.0), Twist(-0.2, 0.5), Twist(0.0, 1.0)):
        free = Guard().check_twist(command, 1.0, lidar_mm=LaserScan.from_ros(open_room, null_range="no_return"))
        assert free.valid, free.reasons


def test_a_closed_room_is_judged_by_its_walls_under_both_readings():
    """Walls at 1 m all round, three beams behind ``null`` (a dark patch of wall, or a failed beam)."""
    closed = room("1.0", nulls={359, 0, 1})  # beam 0 is straight behind
    for null_range in ("unknown", "no_return"):
        scan = LaserScan.from_ros(closed, null_range=null_range)
        assert Guard().check_twist(Twist(0.3, 0.0), 1.0, lidar_mm=scan).valid
        into_the_wall = Guard().check_twist(Twist(0.3, 0.0), 3.0, lidar_mm=scan)
        assert not into_the_wall.valid  # the 170 mm disc meets the wall 1 m ahead after 0.83 m
        assert into_the_wall.collision_time_s == pytest.approx((1000.0 - 170.0) / 300.0)
    back = Twist(-0.3, 0.0)
    assert not Guard().check_twist(back, 1.0, lidar_mm=LaserScan.from_ros(closed)).valid  # into what it cannot see
    assert Guard().check_twist(back, 1.0, lidar_mm=LaserScan.from_ros(closed, null_range="no_return")).valid


def test_no_return_reads_a_blinded_sector_as_free_space():
    """Why ``unknown`` is the default: a sector whose beams failed (``nan`` from the driver, ``null`` on the
    wire) reads as free with ``no_return``, and the guard lets the robot drive through the wall there."""
    blinded = room("1.0", nulls=range(150, 211))  # 30 degrees either side of the heading
    through = Guard().check_twist(Twist(0.3, 0.0), 5.0, lidar_mm=LaserScan.from_ros(blinded, null_range="no_return"))
    assert through.valid  # 1.5 m ahead, through the wall at 1 m it could not see
    assert not Guard().check_twist(Twist(0.3, 0.0), 5.0, lidar_mm=LaserScan.from_ros(blinded)).valid


@pytest.mark.parametrize("change, message", [
    ({"angle_increment": None}, "not a sensor_msgs/LaserScan: no angle_increment"),
    ({"angle_min": True}, "LaserScan.angle_min must be a number, got True"),
    ({"range_max": "3.5"}, "LaserScan.range_max must be a number, got '3.5'"),
    ({"range_min": 10**400}, "LaserScan.range_min must be a number, got an integer of 1329 bits"),
    ({"angle_min": {"x": 1.0}}, "LaserScan.angle_min must be a number"),
    ({"ranges": "1.0, 2.0"}, "LaserScan.ranges must be a sequence of numbers"),
    ({"ranges": {"0": 1.0}}, "LaserScan.ranges must be a sequence of numbers"),
    ({"ranges": [1.0] * 359 + [10**400]}, r"LaserScan.ranges\[359\] must be a number of metres, got an integer"),
    ({"ranges": [1.0] * 359 + [False]}, r"LaserScan.ranges\[359\] must be a number of metres, got False"),
    ({"ranges": [[1.0]] * 360}, r"LaserScan.ranges\[0\] must be a number of metres"),
    ({"scan_time": "0.1"}, "LaserScan.scan_time must be a number of seconds"),
    ({"header": "base_scan"}, "LaserScan.header must be an object"),
    ({"intensities": 0}, "LaserScan.intensities must be a list"),
    ({"angle_maximum": 3.1}, "not a sensor_msgs/LaserScan: unknown field 'angle_maximum'"),
])
def test_a_rosbridge_scan_that_is_not_a_laser_scan_is_a_clear_error(change, message):
    scan = room("1.0")
    for name, value in change.items():
        if value is None:
            del scan[name]
        else:
            scan[name] = value
    with pytest.raises(ValueError, match=message):
        LaserScan.from_ros(scan)


def test_a_null_range_is_read_only_as_asked():
    with pytest.raises(ValueError, match="null_range must be one of unknown, no_return, got 'free'"):
        LaserScan.from_ros(room("1.0"), null_range="free")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"ranges\[3\] is null .* null_range"):
        LaserScan(angle_min=0.0, angle_increment=DEG, ranges=[1.0, 1.0, 1.0, None], range_min=0.1, range_max=5.0)


json_values = st.recursive(st.none() | st.booleans() | st.floats() | st.integers(min_value=-10**400, max_value=10**400)
                           | st.text(max_size=8),
                           lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=4), inner,
                                                                                        max_size=4), max_leaves=12)


@settings(max_examples=300, deadline=None)
@given(st.sampled_from(["angle_min", "angle_max", "angle_increment", "range_min", "range_max", "ranges", "header",
                        "scan_time", "intensities"]), json_values)
def test_any_json_in_any_field_is_read_or_refused_with_a_value_error(name, value):
    scan = room("1.0")
    scan[name] = value
    try:
        LaserScan.from_ros(scan).to_lidar_scan()
    except ValueError as error:
        assert name in str(error)


def scan_90(count: int, **fields) -> LaserScan:
    """A scan declaring +-45 degrees in 1-degree steps (91 beams when consistent), free all round."""
    return LaserScan(**{"angle_min": -45 * DEG, "angle_max": 45 * DEG, "angle_increment": DEG,
                        "ranges": [math.inf] * count, "range_min": 0.05, "range_max": 8.0, **fields})


def test_a_scan_whose_angle_max_contradicts_its_beams_is_refused():
    """Issue 52 item 13: +-45 degrees declared but 360 ranges carried let a backward command pass."""
    backward = [{"command": "straight", "direction": "backward", "distance": 300}]
    assert not Guard(["lidar_clearance"]).check(backward, lidar_mm=scan_90(91)).valid
    for count in (360, 90 - 1, 93):
        with pytest.raises(ValueError, match=r"LaserScan contradicts itself: angle_min .* angle_increment .* "
                                             r"angle_max is 0\.785"):
            scan_90(count)
    message = SimpleNamespace(angle_min=-45 * DEG, angle_max=45 * DEG, angle_increment=DEG, range_min=0.05,
                              range_max=8.0, ranges=[math.inf] * 360)
    with pytest.raises(ValueError, match="contradicts itself"):
        LaserScan.from_ros(message)
    assert scan_90(360, angle_max=None).ranges.size == 360  # none declared: nothing to contradict


@pytest.mark.parametrize("count, angle_max_deg", [
    (91, 45.0), (91, 45.49), (91, 44.51),  # REP 117: the last beam at angle_max, within half a step
    (90, 45.0),  # the end of the last beam's sector (Nav2's collision-monitor tests: 360 beams, 0 to 2 pi)
])
def test_angle_max_within_half_an_increment_of_the_last_beam_is_read(count, angle_max_deg):
    assert scan_90(count, angle_max=angle_max_deg * DEG).ranges.size == count


def test_a_reversed_scan_checks_angle_max_too():
    assert scan_90(91, angle_min=45 * DEG, angle_max=-45 * DEG, angle_increment=-DEG).ranges.size == 91
    with pytest.raises(ValueError, match="contradicts itself"):
        scan_90(91, angle_min=45 * DEG, angle_max=-45 * DEG, angle_increment=DEG)


@pytest.mark.parametrize("name", ["angle_min", "angle_increment", "angle_max", "range_min", "range_max"])
@pytest.mark.parametrize("value", ["1", "1_0", b"1", True])
def test_a_scan_reads_no_text_or_bool_as_a_number(name, value):
    with pytest.raises(ValueError, match=f"LaserScan.{name} must be a number"):
        scan_90(91, **{name: value})


# --- a mounted scanner's own view: what it saw, from where it stood ------------------------------

def _free_m(ranges: list[float], range_min: float, range_max: float) -> np.ndarray:
    """Each beam's free segment (m from the scanner): to its return, to the range when it got none, 0
    when too close to measure; NaN when it gave no reading."""
    r = np.array(ranges, dtype=float)
    with np.errstate(invalid="ignore"):
        returned = np.isfinite(r) & (r >= range_min) & (r <= range_max)
        free = np.isposinf(r) | (np.isfinite(r) & (r > range_max))
    return np.where(returned, r, np.where(free, range_max, np.where(np.isneginf(r), 0.0, np.nan)))


def test_a_mounted_scanner_keeps_its_view_from_its_mount_and_a_centred_one_needs_none():
    """Rebinned round the centre, a scanner 120 mm ahead leaves a bin at a post's shadow edge that no
    beam ends in (unknown at every range); its view from the mount is the scan a scanner at the centre
    with the same beams gives, so nothing it saw is lost there and nothing it did not see is gained."""
    ranges = [0.6 if 10 <= k <= 30 else 3.0 for k in range(360)]  # a post 10-30 deg left, 0.6 m from the scanner
    mounted = LaserScan(angle_min=0.0, angle_increment=DEG, ranges=ranges, range_min=0.05, range_max=8.0,
                        mount=SensorMount(120.0, 0.0, 0.0))
    centred = LaserScan(angle_min=0.0, angle_increment=DEG, ranges=ranges, range_min=0.05, range_max=8.0)
    converted, plain = mounted.to_lidar_scan(), centred.to_lidar_scan()
    assert np.isnan(converted.ranges_mm).any()  # round the centre: a bin with no beam in it
    assert isinstance(converted, MountedScan) and converted.origin_mm == (120.0, 0.0)
    assert type(plain) is LidarScan  # a centred scanner: the bins are its view
    np.testing.assert_array_equal(converted.view.ranges_mm, plain.ranges_mm)
    assert converted.view.max_range_mm == plain.max_range_mm == 8000.0


@settings(max_examples=200, deadline=None)
@given(st.floats(-400, 400), st.floats(-400, 400), st.floats(-180, 180), st.sampled_from([0.25, 0.7, 1.0, 2.5, 4.0]),
       st.floats(-math.pi, math.pi), st.data())
def test_a_mounted_scanners_view_holds_as_seen_only_what_a_beam_saw_free(x_mm, y_mm, yaw_deg, step_deg, angle_min,
                                                                         data):
    """Every bin of the view is seen out to where a beam of the scanner, from the mount and within half
    a bin of the bin's bearing, saw free, and no farther; a bin no beam read into is unknown. A centred
    scanner's scan is unchanged: a plain scan, its own view."""
    count = data.draw(st.integers(1, int(360 / step_deg)))
    ranges = data.draw(st.lists(st.one_of(st.floats(0.0, 9.0), st.just(math.inf), st.just(-math.inf),
                                          st.just(math.nan)), min_size=count, max_size=count))
    scan = LaserScan(angle_min=angle_min, angle_increment=step_deg * DEG, ranges=ranges, range_min=0.1,
                     range_max=8.0, mount=SensorMount(x_mm, y_mm, yaw_deg))
    converted = scan.to_lidar_scan()
    if x_mm == 0.0 and y_mm == 0.0:
        assert type(converted) is LidarScan
        return
    assert isinstance(converted, MountedScan) and converted.origin_mm == (x_mm, y_mm)
    view = converted.view
    free_mm = _free_m(ranges, 0.1, 8.0) * 1000.0
    bearings = np.degrees(angle_min + np.arange(count) * step_deg * DEG) + yaw_deg
    half = view.increment_deg / 2.0
    for k, value in enumerate(view.ranges_mm):
        off = np.abs((bearings - view.angles_deg[k] + 180.0) % 360.0 - 180.0)
        if np.isnan(value):  # unknown: no beam that read anything points into the bin
            assert not (~np.isnan(free_mm) & (off < half - 1e-6)).any()
        else:
            into = ~np.isnan(free_mm) & (off <= half + 1e-6)
            assert (free_mm[into] >= min(value, view.max_range_mm) - 1e-6).any()
