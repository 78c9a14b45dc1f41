"""The guard against Nav2's collision monitor: Nav2's own test cases, then generated scenes.

The outside reference is Nav2's ``nav2_collision_monitor`` (ros-navigation/navigation2, commit
``a3a97043``): its approach polygon simulates the held velocity in steps and stops or slows the
robot by the time before collision. ``nav2_reference.py`` is a line-by-line Python reading of its
algorithm; it is first held to Nav2's own expected values (the ``*_reference_*`` tests), then the
guard with its robot defaults (``Guard()``: ``command_limits`` + ``swept_body``) is held to the same
cases and to generated ones. The guard is exact where Nav2 steps (its time may differ by one
simulation step) and stricter by design where Nav2 counts no point: unseen space (docs/robots.md).

How the cases are posed: Nav2's test sources are placed at the base (identity TF, as its tests send);
a range sensor's or a point cloud's points are given to the guard as a scan whose other beams are
free, since Nav2 treats every place without a point as free.
"""

from __future__ import annotations

import math
from types import SimpleNamespace

import numpy as np
import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from safeembodai_core import Guard, RobotSpec, SlowdownZone
from safeembodai_core.geometry import Motion
from safeembodai_core.models import LidarScan
from safeembodai_core.ros import LaserScan, Twist

import body_depth
import nav2_reference as nav2

SQUARE_05 = [(0.5, 0.5), (0.5, -0.5), (-0.5, -0.5), (-0.5, 0.5)]  # polygons_test.cpp:48-49
# SIMULATION_TIME_STEP, TIME_BEFORE_COLLISION: polygons_test.cpp:70-71, collision_monitor_node_test.cpp:63-64
DT, T = 0.01, 1.0


def _mm(points_m):
    return [(x * 1000.0, y * 1000.0) for x, y in points_m]


def scan_of(points_m, beams: int = 7200, max_range_m: float = 30.0) -> LidarScan:
    """Points (metres) as a scan in the rules' format: each on its nearest of ``beams`` beams, the
    others free (the guard's resolution here: a point moves by at most half a beam sideways)."""
    ranges = np.full(beams, np.inf)
    for x, y in points_m:
        k = int(round(math.degrees(math.atan2(y, x)) / (360.0 / beams))) % beams
        ranges[k] = min(ranges[k], math.hypot(x, y) * 1000.0)
    return LidarScan(ranges, max_range_m * 1000.0)


def nav2_scan(dist: float) -> LaserScan:
    """collision_monitor_node_test.cpp:562-581 (``publishScan``): 360 beams of 1 degree from 0, all ``dist``."""
    msg = SimpleNamespace(angle_min=0.0, angle_max=2 * math.pi, angle_increment=math.pi / 180, range_min=0.1,
                          range_max=dist + 1.0, ranges=[dist] * 360)
    return LaserScan.from_ros(msg)


def square_robot(half_m: float, holonomic: bool = True) -> RobotSpec:
    return RobotSpec(radius_mm=half_m * 1000 * math.sqrt(2), footprint_mm=_mm(
        [(half_m, half_m), (half_m, -half_m), (-half_m, -half_m), (-half_m, half_m)]), holonomic=holonomic)


def disc_robot(radius_m: float) -> RobotSpec:
    r = radius_m * 1000.0
    return RobotSpec(radius_mm=r, width_mm=2 * r, length_mm=2 * r, holonomic=True)


# --- the reference reproduces Nav2's own expectations ------------------------------------------------

COLLISION_TIME_CASES = [  # polygons_test.cpp:907-992 (testPolygonGetCollisionTime), footprint SQUARE_POLYGON
    ("forward", nav2.Velocity(0.5, 0.0, 0.0), [(0.7, -0.01), (0.7, 0.01)], 0.4, DT),  # :914-925
    ("backward", nav2.Velocity(-0.5, 0.0, 0.0), [(-0.7, -0.01), (-0.7, 0.01)], 0.4, DT),  # :927-934
    ("sideways", nav2.Velocity(0.0, 0.5, 0.0), [(-0.01, 0.6), (0.01, 0.6)], 0.2, DT),  # :936-943
    # :945-967: Nav2 writes the expectation as `45 / 180 * M_PI`, which is 0 in integer arithmetic; the
    # points (0.49, +-0.01) lie inside the 0.5 m square already, so 0 is the right answer all the same
    ("rotation", nav2.Velocity(0.0, 0.0, 1.0), [(0.49, -0.01), (0.49, 0.01)], 0.0, 1e-5),
    ("inside", nav2.Velocity(0.5, 0.0, 0.0), [(0.1, -0.01), (0.1, 0.01)], 0.0, 1e-5),  # :969-981
    ("out of reach", nav2.Velocity(0.5, 0.0, 0.0), [(1.1, -0.01), (1.1, 0.01)], None, 0.0),  # :983-991
]


@pytest.mark.parametrize("name, vel, points, expected, tolerance", COLLISION_TIME_CASES,
                         ids=[c[0] for c in COLLISION_TIME_CASES])
def test_the_reference_reproduces_nav2s_collision_times(name, vel, points, expected, tolerance):
    shape = nav2.Shape(polygon=SQUARE_05, time_before_collision=T, simulation_time_step=DT, min_points=2)
    got = nav2.collision_time(shape, points, vel)
    if expected is None:
        assert got < 0.0
    else:
        assert got == pytest.approx(expected, abs=tolerance)


def test_the_reference_reproduces_nav2s_approach_and_rotation_cases():
    # collision_monitor_node_test.cpp:1048-1115 (testProcessApproach): circle of 1 m, scan at 1.2 m
    circle = nav2.Shape(radius=1.0, min_points=2)
    points = nav2.scan_points(0.0, math.pi / 180, [1.2] * 360, 0.1, 2.2)
    out = nav2.approach(circle, points, nav2.Velocity(0.5, 0.2, 0.0))
    ratio = (0.2 / 0.538516481) / T  # :1080-1082
    assert out.x == pytest.approx(0.5 * ratio, abs=0.5 * DT / T)
    assert out.y == pytest.approx(0.2 * ratio, abs=0.2 * DT / T)
    assert nav2.approach(circle, nav2.scan_points(0.0, math.pi / 180, [3.0] * 360, 0.1, 4.0),
                         nav2.Velocity(0.5, 0.2, 0.0)) is None  # :1067-1074
    assert nav2.collision_time(circle, nav2.scan_points(0.0, math.pi / 180, [0.5] * 360, 0.1, 1.5),
                               nav2.Velocity(1e9, 0.2, 0.0)) == 0.0  # :1091-1099
    # :1117-1186 (testProcessApproachRotation): 1 m square footprint, a range sensor (fov pi/10,
    # obstacles_angle pi/200 at :465) at 1.4 m, turning at pi/4 rad/s -> pi/5
    square = nav2.Shape(polygon=[(1.0, 1.0), (1.0, -1.0), (-1.0, -1.0), (-1.0, 1.0)], min_points=2)
    reading = nav2.range_points(1.4, math.pi / 10, math.pi / 200)
    out = nav2.approach(square, reading, nav2.Velocity(0.0, 0.0, math.pi / 4))
    assert out.tw == pytest.approx(math.pi / 5, abs=(math.pi / 4) * (DT / T))  # :1150-1153
    # :1188-1254 (testCrossOver), stage 1: two cloud points at 2.5 m, circle of 1 m, 3 m/s -> 1.5 m/s
    out = nav2.approach(circle, [(2.5, 0.01), (2.5, -0.01)], nav2.Velocity(3.0, 0.0, 0.0))
    assert out.x == pytest.approx(3.0 * (1.5 / 3.0) / T, abs=3.0 * DT / T)  # :1213-1216


# --- the guard on Nav2's cases -----------------------------------------------------------------------

@pytest.mark.parametrize("name, vel, points, expected, tolerance", COLLISION_TIME_CASES,
                         ids=[c[0] for c in COLLISION_TIME_CASES])
def test_guard_time_before_collision_on_nav2s_cases(name, vel, points, expected, tolerance):
    guard = Guard(robot=RobotSpec(radius_mm=707.1, footprint_mm=_mm(SQUARE_05), holonomic=True))
    report = guard.check_twist(Twist(vel.x, vel.tw, vel.y), T, lidar_mm=scan_of(points))
    if expected is None:
        assert report.valid and report.collision_time_s is None
    else:
        assert not report.valid and report.contact == "return"
        # exact where Nav2 steps: within one simulation step (Nav2 reports the step before the touch)
        assert report.collision_time_s == pytest.approx(expected, abs=max(tolerance, DT))


def test_guard_limit_on_nav2s_approach_case():
    """collision_monitor_node_test.cpp:1048-1115: a 1 m circle, a holonomic command (0.5, 0.2) m/s."""
    guard = Guard(robot=disc_robot(1.0))
    far = guard.limit_twist(Twist(0.5, 0.0, 0.2), T, lidar_mm=nav2_scan(3.0))
    assert not far.limited and far.twist == Twist(0.5, 0.0, 0.2)  # :1067-1074
    near = guard.limit_twist(Twist(0.5, 0.0, 0.2), T, lidar_mm=nav2_scan(1.2))
    ratio = (0.2 / 0.538516481) / T  # :1080-1082
    assert near.twist.linear_x == pytest.approx(0.5 * ratio, abs=0.5 * DT / T)  # :1083-1084
    assert near.twist.linear_y == pytest.approx(0.2 * ratio, abs=0.2 * DT / T)  # :1085-1086
    assert near.twist.angular_z == 0.0 and near.reasons[0].startswith("approach:")
    inside = guard.limit_twist(Twist(1_000_000_000.0, 0.0, 0.2), T, lidar_mm=nav2_scan(0.5))  # :1091-1099
    assert inside.stopped and inside.twist == Twist(0.0, 0.0, 0.0)
    again = guard.limit_twist(Twist(0.5, 0.0, 0.2), T, lidar_mm=nav2_scan(3.0))  # :1102-1111
    assert not again.limited


def _range_scan(dist: float) -> LidarScan:
    """collision_monitor_node_test.cpp:655-670 (``publishRange``: fov pi/10, max_range dist + 0.1),
    read as Nav2's range source reads it (obstacles_angle pi/200, :465), the rest of the circle free
    out to the sensor's range."""
    return scan_of(nav2.range_points(dist, math.pi / 10, math.pi / 200), beams=400, max_range_m=dist + 0.1)


def test_guard_limit_on_nav2s_rotation_case():
    """collision_monitor_node_test.cpp:1117-1186: a 1 m square turning at pi/4 rad/s towards a range
    reading. Nav2's test counts two points (MIN_POINTS, :59); with the robot default (one point is
    a collision) the guard slows down a little earlier."""
    twist = Twist(0.0, math.pi / 4)
    as_nav2 = Guard(["command_limits", {"use": "swept_body", "options": {"min_points": 2}}], robot=square_robot(1.0))
    assert not as_nav2.limit_twist(twist, T, lidar_mm=_range_scan(2.0)).limited  # :1138-1144
    limited = as_nav2.limit_twist(twist, T, lidar_mm=_range_scan(1.4))
    assert limited.twist.angular_z == pytest.approx(math.pi / 5, abs=(math.pi / 4) * (DT / T))  # :1147-1157
    assert as_nav2.limit_twist(twist, T, lidar_mm=_range_scan(0.5)).stopped  # :1160-1167
    assert not as_nav2.limit_twist(twist, T, lidar_mm=_range_scan(2.5)).limited  # :1170-1180
    default = Guard(robot=square_robot(1.0)).limit_twist(twist, T, lidar_mm=_range_scan(1.4))
    assert default.twist.angular_z < limited.twist.angular_z
    # and the paper's rule does not slow the turn at all: V(C) accepts every turn (tex:338)
    paper = Guard(["command_limits", "lidar_clearance"], robot=square_robot(1.0)).limit_twist(
        twist, T, lidar_mm=_range_scan(1.4))
    assert not paper.limited


def test_guard_slowdown_and_stop_zones_on_nav2s_cases():
    """collision_monitor_node_test.cpp:872-955 (testProcessStopSlowdownLimit) with its stop (1 m) and
    slowdown (2 m, ratio 0.7) squares as zones, no approach rule; Nav2's ``limit`` zone (stage 2) has
    no counterpart here (a speed cap, not built)."""
    zones = [SlowdownZone(0.0, polygon_mm=square_robot(1.0).footprint_mm, name="Stop", min_points=2),
             SlowdownZone(0.7, polygon_mm=square_robot(2.0).footprint_mm, name="SlowDown", min_points=2)]
    guard = Guard([], robot=RobotSpec(holonomic=True))
    twist = Twist(0.5, 0.1, 0.2)
    assert not guard.limit_twist(twist, T, slowdown=zones, lidar_mm=nav2_scan(4.5)).limited  # :889-896
    slow = guard.limit_twist(twist, T, slowdown=zones, lidar_mm=nav2_scan(1.5))  # :913-923
    assert slow.twist == pytest.approx(Twist(0.5 * 0.7, 0.1 * 0.7, 0.2 * 0.7)) and slow.zones == ["SlowDown"]
    stop = guard.limit_twist(twist, T, slowdown=zones, lidar_mm=nav2_scan(0.5))  # :926-935
    assert stop.stopped and "Stop" in stop.zones
    assert not guard.limit_twist(twist, T, slowdown=zones, lidar_mm=nav2_scan(4.5)).limited  # :938-948


def test_guard_cross_over_of_approach_and_slowdown():
    """collision_monitor_node_test.cpp:1188-1254 (testCrossOver): slowdown square of 2 m (0.7), approach
    circle of 1 m, two cloud points at 2.5 m and a range reading; the safer of the two wins."""
    guard = Guard(robot=disc_robot(1.0))
    zone = [SlowdownZone(0.7, polygon_mm=square_robot(2.0).footprint_mm, name="SlowDown", min_points=2)]
    cloud = [(2.5, 0.01), (2.5, -0.01)]
    first = guard.limit_twist(Twist(3.0, 0.0), T, slowdown=zone,
                              lidar_mm=scan_of(cloud + nav2.range_points(2.5, math.pi / 10, math.pi / 200)))
    assert first.twist.linear_x == pytest.approx(3.0 * (1.5 / 3.0) / T, abs=3.0 * DT / T)  # :1206-1219
    assert not first.zones
    scene = scan_of(cloud + nav2.range_points(1.5, math.pi / 10, math.pi / 200))
    slow = guard.limit_twist(Twist(0.1, 0.0), T, slowdown=zone, lidar_mm=scene)  # :1222-1232
    assert slow.twist.linear_x == pytest.approx(0.1 * 0.7) and slow.zones == ["SlowDown"] and slow.report.valid
    fast = guard.limit_twist(Twist(1.0, 0.0), T, slowdown=zone, lidar_mm=scene)  # :1237-1248
    assert fast.twist.linear_x == pytest.approx(1.0 * (0.5 / 1.0) / T, abs=1.0 * DT / T)


def test_the_paper_rule_misses_what_nav2_sees():
    """The issue's two collisions: a return just off the heading, inside the swept path but outside
    V(C)'s ±30 degrees, and a long body's corner when it turns in place. Nav2 acts on both; so does
    the robot default; the paper's rule accepts both."""
    off_heading = [(0.3 * math.cos(math.radians(40)), 0.3 * math.sin(math.radians(40)))]
    shape = nav2.Shape(radius=0.2, min_points=1)
    assert 0.0 <= nav2.collision_time(shape, off_heading, nav2.Velocity(0.3, 0.0, 0.0)) < T
    scan = scan_of(off_heading, beams=360)
    assert not Guard(robot=disc_robot(0.2)).check_twist(Twist(0.3, 0.0), T, lidar_mm=scan).valid
    assert Guard(["command_limits", "lidar_clearance"], robot=disc_robot(0.2)).check_twist(
        Twist(0.3, 0.0), T, lidar_mm=scan).valid
    long_body = [(0.4, 0.15), (-0.4, 0.15), (-0.4, -0.15), (0.4, -0.15)]
    beside = [(0.0, 0.3)]
    assert 0.0 <= nav2.collision_time(nav2.Shape(polygon=long_body, min_points=1), beside, nav2.Velocity(0, 0, 1.5)) < T
    robot = RobotSpec(radius_mm=427, footprint_mm=_mm(long_body))
    assert not Guard(robot=robot).check_twist(Twist(0.0, 1.5), T, lidar_mm=scan_of(beside, beams=360)).valid
    assert Guard(["command_limits", "lidar_clearance"], robot=robot).check_twist(
        Twist(0.0, 1.0), T, lidar_mm=scan_of(beside, beams=360)).valid


# --- generated scenes --------------------------------------------------------------------------------

BEAMS = 720  # 0.5 degree: the points below sit on beams, so the guard sees them exactly


@st.composite
def scenes(draw):
    if draw(st.booleans()):
        radius = draw(st.floats(0.1, 0.6))
        shape, robot = nav2.Shape(radius=radius, min_points=1), disc_robot(radius)
    else:
        n = draw(st.integers(3, 8))
        cuts = sorted(draw(st.lists(st.floats(0.0, 2 * math.pi), min_size=n, max_size=n, unique=True)))
        gaps = np.diff(cuts + [cuts[0] + 2 * math.pi])
        if min(gaps) < 0.2 or max(gaps) > 2.5:  # keep it well-formed: a star about the centre, no slivers
            cuts = [2 * math.pi * k / n for k in range(n)]
        radii = draw(st.lists(st.floats(0.1, 0.6), min_size=n, max_size=n))  # star-shaped: simple, maybe concave
        polygon = [(r * math.cos(a), r * math.sin(a)) for r, a in zip(radii, cuts)]
        shape = nav2.Shape(polygon=polygon, min_points=1)
        robot = RobotSpec(radius_mm=max(radii) * 1000, footprint_mm=_mm(polygon), holonomic=True)
    vx = draw(st.sampled_from([0.0]) | st.floats(-1.0, 1.0))
    vy = draw(st.sampled_from([0.0]) | st.floats(-0.5, 0.5))
    w = draw(st.sampled_from([0.0]) | st.floats(-1.5, 1.5))
    beams = draw(st.lists(st.integers(0, BEAMS - 1), min_size=1, max_size=25, unique=True))
    ranges = np.full(BEAMS, np.inf)
    ranges[beams] = draw(st.lists(st.floats(50.0, 2500.0), min_size=len(beams), max_size=len(beams)))
    return shape, robot, nav2.Velocity(vx, vy, w), LidarScan(ranges, 30_000.0)


def _fine(shape: nav2.Shape, points, vel) -> float:
    """Nav2's algorithm with a step 20 times finer: where the true touch lies, to within 0.5 ms."""
    fine = nav2.Shape(shape.polygon, shape.radius, T + DT, DT / 20, shape.min_points)
    return nav2.collision_time(fine, points, vel)


def _on_outline(shape: nav2.Shape, points) -> bool:
    """A point on the outline of a shape that is star-shaped about its centre: moved a hair inwards it
    is inside, a hair outwards it is not."""
    def inside(x: float, y: float, k: float) -> int:
        return shape.points_inside([(x * k, y * k)])

    return any(inside(x, y, 1 - 1e-7) != inside(x, y, 1 + 1e-7) for x, y in points)


def _oblique_arc() -> tuple:
    """A holonomic disc sliding backwards and sideways on an arc into a return behind it, met obliquely:
    Nav2's 10 ms Euler steps touch 12 ms after the true arc does (its finer run: 0.5781 s; the guard's 0.5781)."""
    ranges = np.full(720, np.inf)
    ranges[0], ranges[297] = 450.0, 680.0
    return (nav2.Shape(None, 0.44921875, T, DT, 1),
            RobotSpec(radius_mm=449.21875, width_mm=898.4375, length_mm=898.4375, holonomic=True),
            nav2.Velocity(x=-0.8203125, y=-0.1875, tw=-0.1875), LidarScan(ranges_mm=ranges, max_range_mm=30000.0))


def _split(scan: LidarScan, shape: nav2.Shape) -> tuple[LidarScan, LidarScan]:
    """The scan's returns clear of the shape at the start, and those on or inside its outline (each
    scan with the other's beams free)."""
    points = scan.points() / 1000.0
    held = np.array([bool(shape.points_inside([p])) or _on_outline(shape, [p]) for p in points], dtype=bool)
    returns = np.flatnonzero(np.isfinite(scan.ranges_mm))
    clear, on = scan.ranges_mm.copy(), scan.ranges_mm.copy()
    clear[returns[held]], on[returns[~held]] = np.inf, np.inf
    return LidarScan(clear, scan.max_range_mm), LidarScan(on, scan.max_range_mm)


@settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(scenes())
@example(_oblique_arc())
def test_guard_agrees_with_nav2_on_generated_scenes(scene):
    """On the returns clear of the body at the start, the guard with its robot defaults refuses whenever
    Nav2 acts within the horizon, with the same time before collision to within one of Nav2's steps
    (plus its Euler drift on arcs, below); where it refuses and Nav2 does not act, the reason is unseen
    space (stricter by design) or a touch that falls between two of Nav2's sampled poses (the finer
    reference sees it). On a return on or inside the outline Nav2 stops whatever the motion (or, on the
    outline, reads it outside); the guard, by design, refuses only a motion that takes the body deeper
    over it: :func:`_judged_as_deeper`."""
    shape, robot, vel, whole = scene
    scan, on_body = _split(whole, shape)
    points = [(x / 1000.0, y / 1000.0) for x, y in scan.points()]
    shape.time_before_collision, shape.simulation_time_step = T, DT
    t_nav2 = nav2.collision_time(shape, points, vel) if points else -1.0
    # Nav2 simulates poses up to one step past the horizon; the guard is asked about the same span
    report = Guard(robot=robot).check_twist(Twist(vel.x, vel.tw, vel.y), T + DT, lidar_mm=scan)
    obstacle = report.obstacle_time_s
    # Nav2 integrates an arc with Euler steps: its path lags the true arc by up to v * w * T * dt / 2
    drift_s = abs(math.hypot(vel.x, vel.y) * vel.tw) * T * DT / 2 / max(math.hypot(vel.x, vel.y), 1e-9) + 1e-9
    if t_nav2 >= 0.0:
        assert not report.valid
        assert obstacle is not None
        # not before Nav2's step, less its Euler lag; that lag, in time, grows where the body meets the
        # return obliquely (a slow approach along the contact normal): then Nav2's own algorithm with a
        # step 20 times finer says where the true touch lies, and the guard must match it
        assert t_nav2 - 1e-9 <= obstacle + drift_s or abs(_fine(shape, points, vel) - obstacle) <= DT / 20 + drift_s
        assert obstacle <= t_nav2 + DT + drift_s + 2 * DT  # Nav2 reports the step before the touched pose
    elif obstacle is not None:
        fine = _fine(shape, points, vel)
        assert fine >= 0.0 and abs(fine - obstacle) <= DT + drift_s, (fine, obstacle)
    if not report.valid and t_nav2 < 0.0 and obstacle is None:
        assert report.contact == "unseen" and report.unseen_time_s is not None
    _judged_as_deeper(shape, robot, vel, on_body)


def _judged_as_deeper(shape: nav2.Shape, robot: RobotSpec, vel: nav2.Velocity, scan: LidarScan) -> None:
    """Returns the body holds at the start: the guard counts one when the body holds it deeper than
    then -- never later than densely sampled poses of the exact arc see that (``body_depth``), and
    only where one of them lies no shallower a moment after it."""
    held = scan.points() / 1000.0
    if not len(held):
        return
    motion = Motion(vel.x * 1000.0, vel.y * 1000.0, vel.tw, T + DT)
    report = Guard(robot=robot).check_twist(Twist(vel.x, vel.tw, vel.y), T + DT, lidar_mm=scan)
    deeper = body_depth.first_deeper(shape, held, motion, T + DT, 2001, 1e-8)
    obstacle = report.obstacle_time_s
    if deeper >= 0.0:
        assert obstacle is not None and obstacle <= deeper + 1e-9
    if obstacle is not None:
        after = body_depth.depth(shape, body_depth.seen_from_body(motion, min(obstacle + 1e-6, T + DT), held))
        assert np.any(after >= body_depth.depth(shape, held) - 1e-12)
