"""``swept_body``: the exact region the body sweeps, for plans (straights, turns) and held motions."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from safeembodai_core import Guard, RobotSpec
from safeembodai_core.geometry import Body, Motion, contact_times
from safeembodai_core.models import ControlLimits, LidarScan, Pose
from safeembodai_core.ros import LaserScan, SensorMount
from safeembodai_core.ros.laser_scan import MountedScan

LONG = [(400.0, 150.0), (-400.0, 150.0), (-400.0, -150.0), (400.0, -150.0)]


def straight(d, direction="forward"):
    return {"command": "straight", "direction": direction, "distance": d}


def turn(a, direction="left"):
    return {"command": "turn", "direction": direction, "angle": a}


def ring(default=3000.0, beams=360, **at):
    ranges = np.full(beams, default)
    for k, r in at.items():
        ranges[int(k[1:])] = r
    return LidarScan(ranges, 8000.0)


def test_a_return_off_the_heading_inside_the_body_path_is_refused_where_vc_accepts_it():
    scan = ring(b40=250.0)  # 40 deg left, 250 mm: y = 161 mm, inside the 170 mm disc's path
    assert Guard(["lidar_clearance"]).check([straight(350)], lidar_mm=scan).valid
    report = Guard().check([straight(350)], lidar_mm=scan)
    assert not report.valid and "swept_body" in report.reasons[0]
    safe = int(re.search(r"at most (\d+) mm is safe", report.reasons[0]).group(1))
    assert Guard().check([straight(safe)], lidar_mm=scan).valid  # following the advice passes
    assert not Guard().check([straight(safe + 2)], lidar_mm=scan).valid


def test_a_long_body_turning_in_place_sweeps_its_corners():
    robot = RobotSpec(radius_mm=428, footprint_mm=LONG)
    scan = ring(b90=300.0)  # beside the body: clear of its side (150 mm), inside its corners' circle
    guard = Guard(robot=robot)
    assert guard.check([straight(100)], lidar_mm=scan).valid
    report = guard.check([turn(89)], lidar_mm=scan)
    assert not report.valid and "of this turn is safe" in report.reasons[0]
    safe = int(re.search(r"at most (\d+) deg", report.reasons[0]).group(1))
    assert guard.check([turn(safe)], lidar_mm=scan).valid
    assert 55 <= safe <= 61  # the long side reaches 300 mm beside the centre after asin(150/300) short of 90 deg
    assert Guard(["lidar_clearance"], robot=robot).check([turn(89)], lidar_mm=scan).valid  # V(C): turns are valid


def test_later_signals_are_judged_from_the_planned_pose():
    scan = ring(b0=5000.0)
    wall = ring(default=3000.0)
    wall.ranges_mm[80:101] = 400.0  # something 400 mm to the left
    assert Guard().check([straight(300)], lidar_mm=wall).valid
    assert not Guard().check([turn(89), straight(300)], lidar_mm=wall).valid
    assert Guard().check([turn(89), straight(200)], lidar_mm=wall).valid
    assert Guard().check([straight(300)], lidar_mm=scan).valid


def test_unseen_space_is_never_free():
    nan_ahead = ring()
    nan_ahead.ranges_mm[0] = np.nan
    report = Guard().check([straight(300)], lidar_mm=nan_ahead)
    assert not report.valid and "no reading" in report.reasons[0]
    short_range = LidarScan(np.full(360, np.inf), 400.0)  # free only out to 400 mm
    report = Guard().check([straight(300)], lidar_mm=short_range)
    assert not report.valid and "range" in report.reasons[0]
    assert Guard().check([straight(200)], lidar_mm=short_range).valid


def test_a_shadow_behind_a_return_beside_an_arc_is_unseen():
    ranges = np.full(720, 3000.0)
    ranges[100:110] = 600.0  # a post 50-55 deg left at 600 mm: the arc left passes into its shadow
    scan = LidarScan(ranges, 8000.0)
    report = Guard().check_twist((0.4, 0.9), 2.0, lidar_mm=scan)
    assert not report.valid and report.unseen_time_s is not None


def test_margin_and_min_points():
    scan = ring(b0=500.0)
    assert Guard().check([straight(320)], lidar_mm=scan).valid
    padded = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": 50}}])
    assert not padded.check([straight(320)], lidar_mm=scan).valid
    assert padded.check([straight(270)], lidar_mm=scan).valid
    two = Guard([{"use": "swept_body", "options": {"min_points": 2}}])
    assert two.check([straight(340)], lidar_mm=scan).valid  # one return alone is noise to it
    scan.ranges_mm[1] = 500.0
    assert not two.check([straight(340)], lidar_mm=scan).valid


def test_bad_footprints_and_options_are_clear_errors():
    with pytest.raises(ValueError, match=r"RobotSpec.footprint_mm is not a simple polygon"):
        RobotSpec(footprint_mm=[(0, 0), (100, 100), (0, 100), (100, 0)])
    with pytest.raises(ValueError, match=r"RobotSpec.footprint_mm\[1\] must be finite"):
        RobotSpec(footprint_mm=[(0, 0), (math.nan, 1), (1, 0)])
    with pytest.raises(ValueError, match="encloses no area"):
        RobotSpec(footprint_mm=[(0, 0), (1, 1), (2, 2)])
    with pytest.raises(ValueError, match="3 to 64"):
        RobotSpec(footprint_mm=[(0, 0), (1, 1)])
    with pytest.raises(Exception, match="margin_mm"):
        Guard([{"use": "swept_body", "options": {"margin_mm": -1}}])
    clockwise = RobotSpec(footprint_mm=list(reversed(LONG)))
    assert clockwise.footprint_mm == RobotSpec(footprint_mm=LONG).footprint_mm  # either winding, kept anticlockwise


# --- the exact sweep against dense sampling of poses ------------------------------------------------

def _sampled(points, motion, body, steps=1500):
    """Per point, the first of ``steps`` evenly spaced poses whose body holds it (inf: none)."""
    out = np.full(len(points), np.inf)
    for t in np.linspace(0.0, motion.duration_s, steps + 1):
        x, y, th = motion.pose_at(float(t))
        c, s = math.cos(th), math.sin(th)
        rel = points - np.array([x, y])
        local = np.column_stack((rel[:, 0] * c + rel[:, 1] * s, -rel[:, 0] * s + rel[:, 1] * c))
        out[body.inside(local) & np.isinf(out)] = t
    return out


BODIES = [Body.of(170, None), Body.of(170, None, 40), Body.of(0, LONG), Body.of(0, LONG, 30),
          Body.of(0, [(300, 0), (0, 200), (-100, 0), (0, 60), (-100, -150)])]  # the last is concave


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(range(len(BODIES))), st.floats(-500, 500), st.floats(-300, 300), st.floats(-2, 2),
       st.floats(0.1, 2.0), st.integers(0, 2**31))
@pytest.mark.slow
def test_contact_times_match_densely_sampled_poses(which, vx, vy, w, duration, seed):
    body = BODIES[which]
    motion = Motion(vx, vy, w, duration)
    points = np.random.default_rng(seed).uniform(-1200, 1200, size=(60, 2))
    exact = contact_times(points, motion, body)
    sampled = _sampled(points, motion, body)
    step = duration / 1500
    both = np.isfinite(exact) & np.isfinite(sampled)
    assert np.all(sampled[both] - exact[both] <= step + 1e-9) and np.all(exact[both] <= sampled[both] + 1e-9)
    # a touch the samples miss lasts less than a step; the samples never see one the exact sweep misses
    assert not np.any(np.isinf(exact) & np.isfinite(sampled))


def _seen(points, motion, t):
    """``points`` (start frame) as the body sees them after ``t`` seconds."""
    x, y, th = motion.pose_at(float(t))
    c, s = math.cos(th), math.sin(th)
    rel = points - np.array([x, y])
    return np.column_stack((rel[:, 0] * c + rel[:, 1] * s, -rel[:, 0] * s + rel[:, 1] * c))


def _sampled_escape(points, motion, body, steps=1500):
    """Per point, the first of ``steps`` evenly spaced poses whose body holds it when it started
    outside, or holds it more than a nanometre deeper than at the start when it started on or inside
    (inf: none)."""
    out = np.full(len(points), np.inf)
    start = body.depth(points)
    for t in np.linspace(0.0, motion.duration_s, steps + 1):
        depth = body.depth(_seen(points, motion, t))
        out[np.where(start >= 0.0, depth > start + 1e-6, depth >= 0.0) & np.isinf(out)] = t
    return out


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(range(len(BODIES))), st.floats(-500, 500), st.floats(-300, 300), st.floats(-2, 2),
       st.floats(0.1, 4.0), st.integers(0, 2**31))
@pytest.mark.slow
def test_escape_contact_times_match_densely_sampled_depths(which, vx, vy, w, duration, seed):
    """With ``escape``, a point the body holds at the start counts once it is held deeper than then,
    a point outside once it is touched: never later than densely sampled poses see it, and where it
    counts a held point, the body holds that point no less deep a moment later."""
    body = BODIES[which]
    motion = Motion(vx, vy, w, duration)
    points = np.random.default_rng(seed).uniform(-450, 450, size=(60, 2))
    # a turn that moves no point by more than sweep's _STRAIGHT_ENOUGH_MM (0.01 mm), with no speed, is no
    # motion by the guard's own rule, while the sampled reference would see nanometres of depth change
    assume(not (vx == 0.0 and vy == 0.0 and motion.straight_enough(body.reach_mm + 450.0 * 2 ** 0.5)))
    exact = contact_times(points, motion, body, escape=True)
    sampled = _sampled_escape(points, motion, body)
    held = body.inside(points)
    assert np.array_equal(body.depth(points) >= 0.0, held)
    assert np.all(contact_times(points, motion, body)[held] == 0.0)  # without escape: touched at once
    assert np.all(exact <= sampled + 1e-9)
    assert not np.any(np.isinf(exact) & np.isfinite(sampled))
    touched = ~held & np.isfinite(exact) & np.isfinite(sampled)
    assert np.all(sampled[touched] - exact[touched] <= duration / 1500 + 1e-9)
    # a held point is counted at the start of a stretch along which it lies deeper: the exact time is
    # not early (the sampled one may be later by as long as the point takes to sink a nanometre)
    for k in np.flatnonzero(held & np.isfinite(exact)):
        after = body.depth(_seen(points[k:k + 1], motion, min(exact[k] + 1e-6, duration)))[0]
        assert after >= body.depth(points[k:k + 1])[0] - 1e-9


@pytest.mark.parametrize("margin", [0.0, 30.0])
def test_the_depth_of_a_point_in_a_rectangle_is_its_signed_distance_to_the_outline(margin):
    body = Body.of(0, LONG, margin)
    points = np.random.default_rng(3).uniform(-600, 600, size=(500, 2))
    x, y = np.abs(points[:, 0]) - 400.0, np.abs(points[:, 1]) - 150.0
    outside = np.hypot(np.maximum(x, 0.0), np.maximum(y, 0.0))
    expected = margin + np.where((x <= 0) & (y <= 0), -np.maximum(x, y), -outside)
    assert body.depth(points) == pytest.approx(expected, abs=1e-9)
    disc = Body.of(170, None, margin)
    assert disc.depth(points) == pytest.approx(170 + margin - np.hypot(points[:, 0], points[:, 1]), abs=1e-9)


@pytest.mark.parametrize("vx, vy, w", [(1e-3, 1e-12, 1.4e-90), (1e-3, 0.0, 1e-300), (1e9, 0.0, 1e-15),
                                       (0.3, 0.0, -1e-30)])
def test_pushing_on_a_return_inside_the_body_is_refused_at_0_whatever_the_numbers(vx, vy, w):
    """Tiny or huge speeds and turn rates (a centre of rotation 10^87 mm away) must not lose a return
    the body already holds and drives deeper over: the path filter and the pose are exact as w goes to 0."""
    ranges = np.full(720, np.inf)
    ranges[0] = 50.0
    robot = RobotSpec(radius_mm=500, width_mm=1000, length_mm=1000, holonomic=True)
    report = Guard(robot=robot).check_twist((vx, w, vy), 1.01, lidar_mm=LidarScan(ranges, 30_000.0))
    assert not report.valid and report.collision_time_s == 0.0
    motion = Motion(vx * 1000, vy * 1000, w, 1.0)
    assert np.all(np.isfinite(motion.pose_at(0.5)))


def test_a_subnormal_turn_rate_is_driven_as_the_straight_it_is():
    """sin(wt) / w with w = 5e-324 rounds wt to whole multiples of w: the pose fell short of the path's
    end (1000 of 1250 mm), and the path filter dropped the return the body meets after 2.46 s."""
    assert Motion(500.0, 0.0, 5e-324, 2.5).pose_at(2.5)[:2] == (1250.0, 0.0)
    report = Guard().check_twist((0.5, 5e-324), 2.5, lidar_mm=ring(b0=1400.0))
    assert not report.valid and report.collision_time_s == pytest.approx(2.46)


@pytest.mark.parametrize("vx, vy, w", [(1e-300, 0.0, 1e-300), (0.0, 0.0, 1e-200), (1e-12, 1e-12, 1.4e-90)])
def test_a_body_that_does_not_move_over_a_return_inside_it_is_not_refused(vx, vy, w):
    """No motion, a turn in place of a disc, or a creep of a picometre takes the body no deeper over a
    return it holds (to a nanometre)."""
    ranges = np.full(720, np.inf)
    ranges[0] = 50.0
    robot = RobotSpec(radius_mm=500, width_mm=1000, length_mm=1000, holonomic=True)
    assert Guard(robot=robot).check_twist((vx, w, vy), 1.01, lidar_mm=LidarScan(ranges, 30_000.0)).valid


# --- a body already on a return: what takes it off goes, what takes it deeper does not ---------------

def _held(report, valid):
    return report.valid if valid else (not report.valid and report.collision_time_s == 0.0
                                       and "goes deeper over a return" in report.reasons[-1])


@pytest.mark.parametrize("at", [300.0, 299.9], ids=["on the outline", "0.1 mm inside"])
def test_a_disc_on_a_return_backs_off_it_but_does_not_push_on(at):
    """A return on the disc's outline (Nav2 counts it outside) or just inside it: reversing, a reversing
    arc and a turn in place (a disc turning about its centre takes no point deeper) go; driving on or a
    forward arc is refused from the start. A plan as well."""
    guard = Guard(robot=RobotSpec(radius_mm=300))
    scan = ring(b0=at)
    for twist, valid in [((-0.5, 0.0), True), ((0.5, 0.0), False), ((-0.5, 0.8), True), ((0.5, 0.8), False),
                         ((0.5, -0.8), False), ((0.0, 1.0), True), ((0.0, -1.0), True)]:
        assert _held(guard.check_twist(twist, 1.0, lidar_mm=scan), valid), twist
    assert guard.check([straight(200, "backward")], lidar_mm=scan).valid
    assert guard.check([turn(80), turn(80, "right")], lidar_mm=scan).valid
    report = guard.check([straight(200)], lidar_mm=scan)
    assert not report.valid and report.reasons[0].endswith(
        "goes deeper over a return of the scan 300 mm ahead on the centre line of the robot after 0 mm; "
        "no forward motion is safe here; move off it first")


@pytest.mark.parametrize("at", [400.0, 399.9], ids=["on the outline", "0.1 mm inside"])
def test_a_footprint_on_a_return_backs_off_it_but_does_not_push_on(at):
    """The long body with a return on (or 0.1 mm inside) the middle of its front edge: reversing and a
    reversing arc go, driving on and forward arcs are refused; turning in place either way swings the
    front edge's ends over it (deeper), so it is refused too."""
    guard = Guard(robot=RobotSpec(radius_mm=428, footprint_mm=LONG))
    scan = ring(b0=at)
    for twist, valid in [((-0.5, 0.0), True), ((0.5, 0.0), False), ((-0.5, 0.5), True), ((-0.5, -0.5), True),
                         ((0.5, 0.5), False), ((0.0, 0.3), False), ((0.0, -0.3), False)]:
        assert _held(guard.check_twist(twist, 1.0, lidar_mm=scan), valid), twist
    assert guard.check([straight(200, "backward")], lidar_mm=scan).valid
    assert not guard.check([straight(200)], lidar_mm=scan).valid
    assert not guard.check([turn(10)], lidar_mm=scan).valid


def test_a_footprint_turning_in_place_off_a_return_near_its_corner_goes_only_the_way_that_frees_it():
    """A return on the front edge 100 mm left of the centre line: turning left swings the edge past it
    (out of the body) until the edge comes back round to it, 2 * 14 deg later; turning right swings
    the corner over it. A disc turning in place would take it no deeper either way."""
    guard = Guard(robot=RobotSpec(radius_mm=428, footprint_mm=LONG))
    scan = ring(b14=400.0 / math.cos(math.radians(14)))
    assert _held(guard.check_twist((0.0, 0.3), 1.0, lidar_mm=scan), True)
    assert _held(guard.check_twist((0.0, -0.3), 1.0, lidar_mm=scan), False)
    back = guard.check_twist((0.0, 0.3), 2.0, lidar_mm=scan)  # 34 deg: the edge reaches it again after 28
    assert not back.valid and back.collision_time_s == pytest.approx(math.radians(28) / 0.3, abs=1e-6)
    assert guard.check([turn(20)], lidar_mm=scan).valid and not guard.check([turn(30)], lidar_mm=scan).valid


def test_backing_off_a_return_still_must_not_touch_another_nor_unseen_space():
    """Only the return the body holds may be left behind: one behind it is touched as before, and
    space the scan did not see behind it still refuses the reverse."""
    guard = Guard(robot=RobotSpec(radius_mm=300))
    report = guard.check_twist((-0.5, 0.0), 1.0, lidar_mm=ring(b0=300.0, b180=600.0))
    assert not report.valid and report.collision_time_s == pytest.approx(0.6)
    assert "touches a return of the scan 600 mm behind" in report.reasons[-1]
    limited = guard.limit_twist((-0.5, 0.0), 1.0, lidar_mm=ring(b0=300.0, b180=600.0))
    assert limited.twist.linear_x == pytest.approx(-0.3)
    blind = ring(b0=300.0)
    blind.ranges_mm[170:191] = np.nan
    report = guard.check_twist((-0.5, 0.0), 1.0, lidar_mm=blind)
    assert not report.valid and report.contact == "unseen" and "space the scan did not see" in report.reasons[-1]


# --- a scanner off the robot's centre: unseen space from where it stood --------------------------

EXAMPLE = [(250.0, 170.0), (-200.0, 170.0), (-200.0, -170.0), (250.0, -170.0)]  # docs/examples/robot.yaml's


def room_scan(mount_mm, posts_mm, half_mm=(3000.0, 3000.0), beams=360) -> LaserScan:
    """What a 360-degree scanner at ``mount_mm`` (robot frame) sees of a room ``|x|, |y| <= half_mm``
    about the robot's centre holding round posts ``(x, y, radius)`` (mm): exact ranges, no noise."""
    mx, my = mount_mm
    ranges = []
    for k in range(beams):
        a = -math.pi + k * 2.0 * math.pi / beams
        c, s = math.cos(a), math.sin(a)
        hits = [t for v, o, h in ((c, mx, half_mm[0]), (s, my, half_mm[1])) if abs(v) > 1e-12
                for t in ((h - o) / v, (-h - o) / v) if t > 0]
        for px, py, r in posts_mm:
            b = (px - mx) * c + (py - my) * s
            d2 = b * b - ((px - mx) ** 2 + (py - my) ** 2 - r * r)
            if d2 >= 0 and b - math.sqrt(d2) > 0:
                hits.append(b - math.sqrt(d2))
        ranges.append(min(hits) / 1000.0)
    return LaserScan(angle_min=-math.pi, angle_increment=2.0 * math.pi / beams, ranges=ranges, range_min=0.05,
                     range_max=8.0, mount=SensorMount(*mount_mm))


def _from(x_mm, y_mm, heading_deg):
    return Pose(x_mm=x_mm, y_mm=y_mm, heading_deg=heading_deg)


POST = (750.0, 200.0, 100.0)  # bench/live_wire.py's: 0.75 m ahead, 0.2 m left, 0.1 m across


def test_what_a_mounted_scanner_saw_free_beside_a_post_is_seen():
    """The example robot (scanner 120 mm ahead) by a post: the space the scanner saw free beside it
    is seen, so the held commands that pass with a scanner at the centre pass with the mounted one
    (rebinned round the centre, a bin at the post's shadow edge was unseen at every range, and every
    forward command was refused), and those that reach the post are refused by both."""
    guard = Guard([{"use": "swept_body", "options": {"margin_mm": 50.0}}],
                  robot=RobotSpec(radius_mm=310, footprint_mm=EXAMPLE))
    mounted, centred = room_scan((120.0, 0.0), [POST]), room_scan((0.0, 0.0), [POST])
    for twist, passes in (((0.3, 0.0), True), ((-0.2, 0.3), True), ((0.0, 1.0), True), ((0.5, -0.4), True),
                          ((0.45, 0.0), False), ((0.4, 0.5), False)):
        report = guard.check_twist(twist, 1.0, lidar_mm=mounted)
        assert report.valid == passes == guard.check_twist(twist, 1.0, lidar_mm=centred).valid, (twist, report.reasons)
        assert passes or report.contact == "return"
    # the point 0.31 m ahead and 0.14 m left, which the scanner saw free (a small body set down on it)
    small = Guard(["swept_body"], robot=RobotSpec(radius_mm=20))
    assert small.check([straight(10)], lidar_mm=mounted, since_scan=_from(310.0, 140.0, 24.0)).valid


def test_the_shadow_behind_a_post_stays_unseen_from_a_mounted_scanner():
    """A small body driven along a bearing that passes beside the post goes into its shadow as the
    scanner (120 mm ahead) saw it: refused as it reaches the shadow, not before. The shadow's edge lies
    between the last beam that met the post (26 deg from the scanner) and the first that passed it (27
    deg); its true edge is the tangent at 26.3 deg. The body (20 mm) reaches the tangent 1.46 m out and
    the beam at 26 deg, along which the shadow is sampled, 1.85 m out (as for a scanner at the centre:
    between two beams, a shadow is taken to begin at the nearer one)."""
    guard = Guard(["swept_body"], limits=ControlLimits(max_distance_mm=5000.0), robot=RobotSpec(radius_mm=20))
    scan = room_scan((120.0, 0.0), [POST])
    report = guard.check([turn(25), straight(3000)], lidar_mm=scan)
    assert not report.valid and "space the scan did not see (behind a return)" in report.reasons[0]
    safe = int(re.search(r"at most (\d+) mm is safe", report.reasons[0]).group(1))
    assert 1460 <= safe <= 1900  # rebinned round the centre, a bin with no beam refused it from the start
    assert guard.check([turn(25), straight(safe)], lidar_mm=scan).valid


def test_a_ray_from_the_centre_across_a_mounted_scanners_shadow_is_unseen():
    """Rebinned round the centre, the bins 40-48 deg left held free out to the wall (a beam from the
    scanner, 300 mm ahead, ended there) though their rays from the centre cross the post's shadow as
    the scanner saw it, 0.6-0.8 m out: a small body could drive into it. From the scanner's own view
    the shadow is unseen."""
    post = (500.0, 346.4, 50.0)  # 400 mm from the scanner, 60 deg left of it
    guard = Guard(["swept_body"], limits=ControlLimits(max_distance_mm=5000.0), robot=RobotSpec(radius_mm=30))
    scan = room_scan((300.0, 0.0), [post])
    start = _from(400.0 * math.cos(math.radians(44)), 400.0 * math.sin(math.radians(44)), 44.0)
    assert guard.check([straight(100)], lidar_mm=scan, since_scan=start).valid
    report = guard.check([straight(400)], lidar_mm=scan, since_scan=start)
    assert not report.valid and "space the scan did not see (behind a return)" in report.reasons[0]


@settings(max_examples=60, deadline=None)
@given(st.floats(-300, 300), st.floats(-200, 200),
       st.lists(st.tuples(st.floats(-2000, 2000), st.floats(-2000, 2000), st.floats(60, 250)), min_size=1, max_size=3),
       st.integers(0, 2), st.floats(-1.0, 1.0), st.floats(0.0, 1.0), st.integers(0, 359))
def test_a_body_driven_from_seen_space_into_a_mounted_scanners_shadow_is_refused(mx, my, posts, which, across,
                                                                                 beyond, beam):
    """Space that no beam's free segment covers is never driven into: a small body (40 mm) driven in a
    straight line from a point the scanner saw (halfway along a beam's free segment) to one in a post's
    shadow as the scanner saw it (behind the post, at least a beam's spacing inside its edges) is
    refused, whatever the mounting."""
    mount = np.array([mx, my])
    assume(all(math.hypot(px - mx, py - my) > r + 250 and math.hypot(px, py) > r + 250 for px, py, r in posts))
    px, py, r = posts[which % len(posts)]
    to_post = np.array([px, py]) - mount
    dist = float(np.hypot(*to_post))
    half = math.asin(r / dist) - math.radians(1.5)  # a beam and a half inside the shadow's edges
    assume(half > 0.0)
    bearing = math.atan2(to_post[1], to_post[0]) + across * half
    q = mount + (dist + r + 60.0 + beyond * 4000.0) * np.array([math.cos(bearing), math.sin(bearing)])
    assume(abs(q[0]) < 2940.0 and abs(q[1]) < 2940.0)  # in the room
    scan = room_scan((mx, my), posts)
    a = -math.pi + beam * 2.0 * math.pi / 360
    s = mount + 0.5 * _free_m(scan)[beam] * np.array([math.cos(a), math.sin(a)])
    distance = float(np.hypot(*(q - s)))
    assume(distance > 100.0)
    heading = math.degrees(math.atan2(q[1] - s[1], q[0] - s[0]))
    guard = Guard(["swept_body"], limits=ControlLimits(max_distance_mm=10_000.0), robot=RobotSpec(radius_mm=40))
    report = guard.check([straight(distance)], lidar_mm=scan, since_scan=_from(s[0], s[1], heading))
    assert not report.valid, (s, q)


def _free_m(scan: LaserScan) -> np.ndarray:
    """Each beam's free segment (mm from the scanner)."""
    return np.minimum(np.asarray(scan.ranges, dtype=float), scan.range_max) * 1000.0


@settings(max_examples=60, deadline=None)
@given(st.lists(st.one_of(st.floats(60.0, 6000.0), st.just(math.inf), st.just(math.nan)), min_size=90, max_size=90),
       st.floats(-0.5, 0.5), st.floats(-1.5, 1.5), st.sampled_from([None, (200.0, 0.0, 0.0)]))
def test_a_scan_judged_from_its_own_view_at_the_centre_gets_the_same_verdicts(ranges, vx, w, moved):
    """The view's path (unseen space from the scanner's origin, shifted) at an origin at the centre is
    the plain scan's path: a scanner at the centre is judged as before."""
    plain = LidarScan(np.array(ranges), 8000.0)
    viewed = MountedScan(np.array(ranges), 8000.0, view=LidarScan(np.array(ranges), 8000.0), origin_mm=(0.0, 0.0))
    guard = Guard(["swept_body"], robot=RobotSpec(radius_mm=310, footprint_mm=EXAMPLE))
    since = None if moved is None else _from(*moved)
    a, b = (guard.check_twist((vx, w), 1.0, lidar_mm=scan, since_scan=since) for scan in (plain, viewed))
    assert (a.valid, a.collision_time_s, a.unseen_time_s, a.reasons) == (b.valid, b.collision_time_s, b.unseen_time_s,
                                                                            b.reasons)
