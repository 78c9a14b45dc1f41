"""The futures ``moving_obstacles`` judges a plan against: wandering courses drawn around a
mover's measured velocity (``plugins/validators/moving/futures.py``), and what they change in verdicts:
a mover whose straight course stays clear of the robot's path but that may turn into it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_core.models import Pose
from safeembodai_plugins.validators.moving.futures import WanderingFutures, WanderSettings, yielding
from safeembodai_plugins.validators.moving.tracking import Blob

from .test_moving_obstacles import LABBOT_MM, context_for, go, refusals, rotate, rule

TIMES = np.arange(0.0, 12.0, 0.1)


def mover(velocity=(150.0, 0.0), span_s: float = 5.0) -> Blob:
    return Blob(centre=np.array([1000.0, 2000.0]), radius_mm=LABBOT_MM,
                velocity=None if velocity is None else np.array(velocity), points=8, span_s=span_s)


def test_without_wander_every_course_is_the_straight_line():
    where = WanderingFutures(WanderSettings(wander_deg=0.0, count=16)).at(mover(), TIMES)
    line = np.array([1000.0, 2000.0]) + TIMES[:, None] * np.array([150.0, 0.0])
    assert where.shape == (16, len(TIMES), 2)
    assert np.allclose(where, line[None], atol=1e-6)


def test_the_same_settings_draw_the_same_courses_and_later_noise_never_changes_earlier_parts():
    settings = WanderSettings(seed=7)
    long = WanderingFutures(settings).at(mover(), TIMES)
    short = WanderingFutures(settings).at(mover(), TIMES[:20])  # a fresh instance, a shorter horizon first
    assert np.array_equal(long[:, :20], short)
    assert not np.allclose(long, WanderingFutures(WanderSettings(seed=8)).at(mover(), TIMES))


def test_courses_spread_with_time_at_the_measured_speed():
    where = WanderingFutures(WanderSettings(count=256)).at(mover(), TIMES)
    travelled = np.hypot(*np.moveaxis(where - np.array([1000.0, 2000.0]), -1, 0))
    assert (travelled <= 150.0 * TIMES[None] + 1e-6).all()  # never faster than measured
    bearing = np.degrees(np.arctan2(where[..., 1] - 2000.0, where[..., 0] - 1000.0))
    early, late = np.std(bearing[:, 10]), np.std(bearing[:, 100])  # 1 s and 10 s after the scan
    # heading spread: the chord's own (25 * sqrt(5 / 3) = 32 deg) then 25 deg per square-root second
    assert 20.0 < early < 45.0 and late > early


def test_a_mover_of_unknown_velocity_is_fanned_all_the_way_round():
    where = WanderingFutures(WanderSettings(count=64, wander_deg=0.0, unknown_speed_mm_s=100.0)).at(
        mover(velocity=None), np.array([0.0, 4.0]))
    assert np.allclose(where[:, 0], [1000.0, 2000.0])
    offset = where[:, 1] - np.array([1000.0, 2000.0])
    assert np.allclose(np.hypot(*offset.T), 400.0)
    gaps = np.diff(np.sort(np.degrees(np.arctan2(offset[:, 1], offset[:, 0]))))
    assert gaps.max() < 360.0 / 64 + 1e-6


ROBOT = Pose(x_mm=1000.0, y_mm=3000.0, heading_deg=0.0)
# a Labbot 1200 mm ahead and 500 mm to the robot's left, going the same way at 100 mm/s: its
# straight course never comes within reach of the robot's path (170 + 120 + 80 mm), but a drift of
# a few tens of degrees puts it across the robot's way (the measured misses of the straight-course
# model turned 46-154 deg after the scan)
ALONGSIDE = {"before": [(1700.0, 3500.0, LABBOT_MM)], "now": [(2200.0, 3500.0, LABBOT_MM)]}


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_a_mover_that_may_turn_into_the_path_is_refused_where_a_straight_course_passes(seed):
    context = context_for(ROBOT, ALONGSIDE["now"], ALONGSIDE["before"])
    plan = [go(399), go(399), go(399)]
    assert not refusals(plan, context, rule(wander_deg=0.0, seed=seed))
    refused = refusals(plan, context, rule(seed=seed, cruise_speed_mm_s=None))  # courses at its measured speed
    assert refused and "predicted courses meet this motion" in refused[0].reason
    assert not refusals([go(-399), go(-399)], context, rule(seed=seed))  # backing away from it passes


def test_a_yielding_mover_stops_where_it_first_sees_the_robot_ahead():
    """Two courses at 150 mm/s: one heading straight at a robot standing 1 m away, one passing it
    with its back turned. With ``movers_yield_mm`` 300 the first stops once the robot's body is
    300 mm from its rim (rim gap = distance - 170 - 120), the second never sees it."""
    times = np.arange(0.0, 8.0, 0.1)
    towards = np.column_stack((1000.0 + 150.0 * times, np.full_like(times, 2000.0)))
    away = np.column_stack((1000.0 - 150.0 * times, np.full_like(times, 2200.0)))
    where = np.stack((towards, away))
    heading = np.stack((np.zeros_like(times), np.full_like(times, math.pi)))
    robot = np.tile([2000.0, 2000.0], (len(times), 1))
    held = yielding(where, heading, robot, 170.0, 120.0, 300.0, 60.0)
    stop = np.flatnonzero(1000.0 - 150.0 * times - 290.0 < 300.0)[0]
    assert np.allclose(held[0, :stop + 1], towards[:stop + 1])
    assert np.allclose(held[0, stop:], towards[stop])  # held where it saw the robot
    assert np.allclose(held[1], away)
    assert np.array_equal(yielding(where, heading, robot, 170.0, 120.0, 0.0, 60.0), where)  # 0: never yields


def test_yielding_movers_are_judged_on_where_the_robot_will_be():
    """A Labbot coming head-on along the robot's line: a yielding mover stops short of the waiting
    robot, so a straight that drives at it is still refused (the robot would run into it), while a
    straight backing away passes."""
    before, now = [(3550.0, 3000.0, LABBOT_MM)], [(2800.0, 3000.0, LABBOT_MM)]
    context = context_for(ROBOT, now, before)
    for options in ({}, {"movers_yield_mm": 300.0}):
        assert refusals([go(399), go(399)], context, rule(**options)), options
        assert not refusals([go(-399)], context, rule(**options)), options


def test_a_mover_that_stops_for_the_robot_ahead_lets_a_plan_pass_that_a_blind_one_refuses():
    """A Labbot 1 m to the robot's left and 300 mm ahead, coming at the robot's line at 60 mm/s
    (straight courses, for a verdict that does not depend on draws): blind, it crosses the line as
    the robot drives by; yielding, it sees the robot coming and stops short of the line."""
    context = context_for(ROBOT, [(1300.0, 4000.0, LABBOT_MM)], [(1300.0, 4300.0, LABBOT_MM)])
    plan = [go(399), go(399), go(399)]
    assert refusals(plan, context, rule(wander_deg=0.0))
    assert not refusals(plan, context, rule(wander_deg=0.0, movers_yield_mm=300.0))


def test_the_robot_track_before_a_straight_follows_the_think_time_and_the_earlier_signals():
    """Where a yielding mover sees the robot depends on where the plan has put it: at the start
    pose through the think time (5 s), still there through a 60-degree left turn (1 s at
    60 deg/s), then 399 mm at 60 degrees in 2 s."""
    context = context_for(ROBOT, [], None).advanced(rotate(60)).advanced(go(399))
    track = rule()._track_before(context, np.array([0.0, 5.0, 6.0, 7.0, 8.0]))
    way = np.array([math.cos(math.radians(60)), math.sin(math.radians(60))])
    assert np.allclose(track, [[1000, 3000], [1000, 3000], [1000, 3000], [1000, 3000] + 199.5 * way,
                               [1000, 3000] + 399 * way], atol=1.0)


def test_a_motion_that_gets_out_of_a_movers_way_passes_while_one_towards_it_is_refused():
    """A Labbot coming head-on at 150 mm/s, due to reach the waiting robot: backing away keeps the
    body further from every course than standing still would, so it passes (refusing it would not
    keep the mover away); driving towards it is refused."""
    context = context_for(ROBOT, [(2400.0, 3000.0, LABBOT_MM)], [(3150.0, 3000.0, LABBOT_MM)])
    assert not refusals([go(-399)], context)
    assert refusals([go(399)], context)


def test_courses_are_the_same_across_the_noise_chunks_whatever_the_order_of_the_checks():
    """Noise is drawn in chunks of 128 time steps (12.8 s); a long horizon asked first or last
    gives the same courses, and course 0 is the measured course at any horizon."""
    times = np.arange(0.0, 40.0, 0.1)
    settings = WanderSettings(seed=3)
    first_long = WanderingFutures(settings).at(mover(), times)
    growing = WanderingFutures(settings)
    for end in (20, 150, 300, len(times)):
        growing.at(mover(), times[:end])
    assert np.array_equal(first_long, growing.at(mover(), times))
    assert np.allclose(first_long[0], np.array([1000.0, 2000.0]) + times[:, None] * np.array([150.0, 0.0]))
