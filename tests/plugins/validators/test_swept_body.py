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
from safeembodai_core.models import LidarScan

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
