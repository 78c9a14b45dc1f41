"""A held velocity in the pybullet rooms (``Environment.drive``): the arc, the clock, contact, the caps."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_core.errors import EnvironmentError_
from safeembodai_core.models import Outcome

ROOM = 4000.0


def open_heading(env) -> float:
    scan = env.observe().lidar
    return env.pose().heading_deg + float(scan.angles_deg[int(np.argmax(scan.ranges_mm))])


def test_a_held_velocity_drives_the_arc_it_describes_on_the_rooms_clock(make_env, moves):
    env = make_env("OF")
    env.reset(3)
    moves.face(env, open_heading(env))
    start, heading, clock = env.xy.copy(), env.heading, env.sim_time_s
    done = env.drive(150.0, 20.0, 1.5)  # 225 mm along an arc turning 30 degrees
    assert done.distance_mm == pytest.approx(225.0) and done.angle_deg == pytest.approx(30.0)
    assert not done.stopped and env.sim_time_s - clock == pytest.approx(1.5)
    assert (env.heading - heading) % 360 == pytest.approx(30.0)
    radius = 150.0 / math.radians(20.0)  # the arc's: its chord from start to end
    chord = 2 * radius * math.sin(math.radians(15.0))
    assert math.hypot(*(env.xy - start)) == pytest.approx(chord, rel=1e-3)
    bearing = math.degrees(math.atan2(*(env.xy - start)[::-1]))
    assert (bearing - heading) % 360 == pytest.approx(15.0, abs=0.05)  # the chord at the middle heading


def test_standing_still_lets_time_pass_and_reversing_goes_back(make_env, moves):
    env = make_env("OF")
    env.reset(3)
    moves.face(env, open_heading(env))
    start, clock = env.xy.copy(), env.sim_time_s
    assert env.drive(0.0, 0.0, 2.0).distance_mm == 0.0 and env.sim_time_s - clock == pytest.approx(2.0)
    env.drive(100.0, 0.0, 1.0)
    back = env.drive(-100.0, 0.0, 1.0)
    assert back.distance_mm == pytest.approx(-100.0)
    np.testing.assert_allclose(env.xy, start, atol=1e-6)


def test_driving_into_a_wall_stops_at_contact_and_the_robot_drives_no_more(make_env, moves):
    env = make_env("OF")
    env.reset(6)
    headings = {0.0: ROOM - env.xy[0], 90.0: ROOM - env.xy[1], 180.0: env.xy[0], -90.0: env.xy[1]}
    to_can = math.degrees(math.atan2(*(env.can_xy - env.xy)[::-1]))
    moves.face(env, max(headings, key=lambda h: abs((h - to_can + 180) % 360 - 180)))
    hit = None
    for _ in range(400):
        hit = env.drive(200.0, 0.0, 0.1)
        if hit.stopped:
            break
    assert hit is not None and hit.collided and hit.collision == "self" and hit.hit == "wall"
    x, y = env.xy
    assert min(x, y, ROOM - x, ROOM - y) == pytest.approx(170.0, abs=2.0)  # at contact, not through it
    assert env.outcome() is Outcome.INTERRUPTED
    after = env.drive(-200.0, 0.0, 0.5)
    assert after.stopped and after.distance_mm == 0.0 and "collided" in after.detail


def test_a_command_beyond_the_bases_limits_is_driven_at_them_with_its_curvature(make_env, moves):
    env = make_env("OF")
    env.reset(3)
    moves.face(env, open_heading(env))
    done = env.drive(1000.0, 30.0, 0.5)  # 5x the room's 200 mm/s: the turn rate scaled with it
    assert done.distance_mm == pytest.approx(100.0) and done.angle_deg == pytest.approx(3.0)
    assert "base's limits" in done.detail


@pytest.mark.parametrize("args", [(math.nan, 0.0, 1.0), (0.0, math.inf, 1.0), (10.0, 0.0, -1.0), (10.0, 0.0, 61.0),
                                  (True, 0.0, 1.0)])
def test_a_bad_hold_is_refused_before_anything_moves(make_env, args):
    env = make_env("OF")
    env.reset(3)
    before, clock = env.xy.copy(), env.sim_time_s
    with pytest.raises(EnvironmentError_, match="drive"):
        env.drive(*args)
    np.testing.assert_array_equal(env.xy, before)
    assert env.sim_time_s == clock


def test_labbots_move_through_a_hold_as_through_a_think_time(make_env):
    held, waited = make_env("MO"), make_env("MO", think_time_s=1.0)
    held.reset(11)
    waited.reset(11)
    held.drive(0.0, 0.0, 1.0)
    waited.sense()  # reset's observation owes one think time: it passes now, the robot standing
    np.testing.assert_allclose(held.swarm.xy, waited.swarm.xy, atol=1e-9)
