"""Movers known to cruise at a speed (``moving_obstacles``' ``cruise_speed_mm_s``): scans paired by
the chord such a mover drives, courses at least that fast, and a short chord read as a turn or a
stop. The three cases the option was built for (``docs/evidence/moving_obstacles.md``): Labbots in a column paired
with each other's earlier positions, a pairing four times faster than a Labbot, and a Labbot that
stopped to turn between the scans and then drives off at full speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from safeembodai_plugins.validators.moving.futures import TURN_QUANTILE, WanderingFutures, WanderSettings
from safeembodai_plugins.validators.moving.tracking import Blob, chord_share, chord_share_quantile

from safeembodai_core.models import Pose

from .test_moving_obstacles import LABBOT_MM, context_for, go, refusals, rule

LOOKING_UP = Pose(x_mm=800.0, y_mm=3000.0, heading_deg=0.0)
# two Labbots 1 m apart in a column driving up the room at 150 mm/s, 5 s between the scans: each is
# now 750 mm further on, nearer to where the other one was (250 mm) than to where it was itself
COLUMN = {"before": [(3000.0, 1500.0, LABBOT_MM), (3000.0, 2500.0, LABBOT_MM)],
          "now": [(3000.0, 2250.0, LABBOT_MM), (3000.0, 3250.0, LABBOT_MM)]}


@pytest.mark.parametrize("wander, span", [(25.0, 5.0), (25.0, 9.0), (60.0, 6.0)])
def test_the_expected_chord_is_the_random_walks_root_mean_square(wander, span):
    rng = np.random.default_rng(0)
    dt = 0.01
    heading = np.cumsum(math.radians(wander) * math.sqrt(dt) * rng.standard_normal((4000, int(span / dt))), axis=1)
    chord = np.hypot(np.cos(heading).sum(axis=1) * dt, np.sin(heading).sum(axis=1) * dt) / span
    assert chord_share(wander, span) == pytest.approx(math.sqrt(np.mean(chord ** 2)), abs=0.01)
    assert chord_share(0.0, span) == 1.0 and chord_share(wander, 0.0) == 1.0
    assert chord_share_quantile(wander, span, 0.5) == pytest.approx(np.median(chord), abs=0.02)
    assert chord_share_quantile(wander, span, 0.05) == pytest.approx(np.quantile(chord, 0.05), abs=0.03)


@pytest.mark.parametrize("wander, span", [(0.001, 30.0), (0.01, 0.1), (0.005, 5.0), (0.03, 0.1)])
def test_the_expected_chord_of_a_barely_wandering_mover_is_its_path(wander, span):
    assert chord_share(wander, span) == pytest.approx(1.0, abs=1e-6)


def velocities(options):
    blobs, _ = rule(**options).movers(context_for(LOOKING_UP, COLUMN["now"], COLUMN["before"]))
    return {round(float(b.centre[1]), -2): b.velocity for b in blobs}


def test_a_column_of_movers_is_paired_nearest_first_without_a_cruising_speed_and_rightly_with_one():
    nearest = velocities({})
    assert set(nearest) == {2300.0, 3300.0}
    assert nearest[2300.0][1] < -40.0  # the one behind was taken for the leader going back
    cruising = velocities({"cruise_speed_mm_s": 150.0})
    for velocity in cruising.values():
        assert velocity[0] == pytest.approx(0.0, abs=25.0) and velocity[1] == pytest.approx(150.0, abs=25.0)


def test_a_stopped_mover_near_where_a_cruising_one_was_keeps_its_own_short_chord():
    """Taken greedily, the pair nearest the expected chord (the stopped Labbot and where the cruising
    one was) would leave the cruiser a partner 1.4 m away: the least total keeps both right."""
    before = [(3000.0, 2000.0, LABBOT_MM), (3695.0, 2150.0, LABBOT_MM)]
    now = [(3000.0, 2150.0, LABBOT_MM), (4445.0, 2150.0, LABBOT_MM)]
    blobs, _ = rule(cruise_speed_mm_s=150.0, max_obstacle_speed_mm_s=300.0).movers(context_for(LOOKING_UP, now, before))
    stopped, cruiser = sorted(blobs, key=lambda b: b.centre[0])
    assert stopped.velocity == pytest.approx([0.0, 30.0], abs=15.0)  # 150 mm in 5 s: it stopped
    assert cruiser.velocity == pytest.approx([150.0, 0.0], abs=15.0)


def test_a_pairing_faster_than_max_obstacle_speed_gives_an_unknown_velocity():
    # one Labbot, 1,750 mm on in 5 s (350 mm/s): over 300 mm/s it is not the same obstacle
    before, now = [(3000.0, 1500.0, LABBOT_MM)], [(3000.0, 3250.0, LABBOT_MM)]
    context = context_for(LOOKING_UP, now, before)
    slow, = rule(cruise_speed_mm_s=150.0, max_obstacle_speed_mm_s=300.0).movers(context)[0]
    fast, = rule(cruise_speed_mm_s=150.0, max_obstacle_speed_mm_s=1000.0).movers(context)[0]
    assert slow.velocity is None
    assert fast.velocity == pytest.approx([0.0, 350.0], abs=20.0)


def test_a_cruising_speed_above_the_pairing_limit_is_refused_at_load():
    from pydantic import ValidationError
    from safeembodai_plugins.validators import MovingObstaclesOptions

    with pytest.raises(ValidationError, match="max_obstacle_speed_mm_s"):
        MovingObstaclesOptions(cruise_speed_mm_s=1400.0)
    assert MovingObstaclesOptions(cruise_speed_mm_s=1400.0, max_obstacle_speed_mm_s=2000.0).cruise_speed_mm_s == 1400.0


def mover(speed: float, span_s: float = 5.0) -> Blob:
    return Blob(centre=np.array([1000.0, 2000.0]), radius_mm=LABBOT_MM, velocity=np.array([speed, 0.0]), points=8,
                span_s=span_s)


def starts(futures: WanderingFutures, blob: Blob) -> np.ndarray:
    """Each course's heading off the chord in its first 0.1 s, degrees."""
    _, heading = futures.courses(blob, np.array([0.0, 0.1]))
    return np.degrees((heading[:, 0] + math.pi) % (2 * math.pi) - math.pi)


def test_a_chord_only_a_turn_explains_is_read_as_one_and_a_wandering_one_is_not():
    """A cruiser that only wandered has a chord above the 5th percentile of wandering chords 95% of
    the time: its courses stay around the chord; below it, the shortfall is the share fanned."""
    futures = WanderingFutures(WanderSettings(count=256, cruise_speed_mm_s=150.0))
    rng = np.random.default_rng(1)
    heading = np.cumsum(math.radians(25.0) * math.sqrt(0.05) * rng.standard_normal((2000, 100)), axis=1)
    chords = 150.0 * np.hypot(np.cos(heading).mean(axis=1), np.sin(heading).mean(axis=1))  # 5 s at 150 mm/s
    read_as_turned = np.mean([futures.turned_share(mover(c)) > 0 for c in chords[:400]])
    assert read_as_turned < 0.1
    typical = mover(150.0 * chord_share(25.0, 5.0))
    assert futures.turned_share(typical) == 0.0
    assert np.abs(starts(futures, typical)).max() < 5 * 25.0 * math.sqrt(5.0 / 3.0)


def test_a_short_chord_fans_that_share_of_the_courses_at_the_cruising_speed():
    futures = WanderingFutures(WanderSettings(count=256, cruise_speed_mm_s=150.0))
    least = 150.0 * chord_share_quantile(25.0, 5.0, TURN_QUANTILE)
    half = mover(0.5 * least)
    assert futures.turned_share(half) == pytest.approx(0.5)
    assert 100 < futures.turned_courses(half) < 156  # about half of 256
    off = np.abs(starts(futures, half))
    assert 0.08 < np.mean(off > 120.0) < 0.26  # half fanned evenly, a third of those beyond 120 deg: 1/6
    where = futures.at(half, np.array([0.0, 1.0]))
    travelled = np.hypot(*(where[:, 1] - where[:, 0]).T)
    assert travelled[0] == pytest.approx(0.5 * least, rel=0.01)  # course 0: the measured course
    # the others cruise: a 1 s arc of a wandering course, its chord a little under 150 mm
    assert (travelled[1:] <= 150.0 + 1e-6).all() and np.median(travelled[1:]) > 145.0
    still = mover(10.0)  # 50 mm in 5 s: no direction at all
    assert futures.turned_share(still) == 1.0 and futures.turned_courses(still) == 255  # all but course 0
    quadrants = np.floor((starts(futures, still)[1:] + 180.0) / 90.0)
    assert set(quadrants.tolist()) == {0.0, 1.0, 2.0, 3.0}
    assert starts(futures, still)[0] == pytest.approx(0.0)


def test_without_a_cruising_speed_nothing_is_fanned():
    futures = WanderingFutures(WanderSettings(count=64))
    assert futures.turned_share(mover(10.0)) == 0.0
    where = futures.at(mover(10.0), np.array([0.0, 10.0]))
    assert np.hypot(*(where[:, 1] - where[:, 0]).T).max() <= 100.0 + 1e-6


def test_a_mover_that_stopped_to_turn_is_refused_in_the_way_only_with_a_cruising_speed():
    """It drove 200 mm in 5 s, away from the robot's line: it stopped or turned for most of that
    time. Its courses at 40 mm/s stay clear of a straight ahead; a Labbot cruising at 150 mm/s that
    turned may be on the robot's line by the time the robot gets there."""
    robot = Pose(x_mm=1000.0, y_mm=3000.0, heading_deg=0.0)
    before, now = [(1900.0, 2450.0, LABBOT_MM)], [(1900.0, 2250.0, LABBOT_MM)]
    context = context_for(robot, now, before)
    assert not refusals([go(399), go(399)], context, rule())
    refused = refusals([go(399), go(399)], context, rule(cruise_speed_mm_s=150.0))
    assert refused and "at most" in refused[0].reason
    assert "may have turned or stopped" in refused[0].reason and " of its courses go any way" in refused[0].reason
