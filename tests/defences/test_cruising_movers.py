"""Movers known to cruise at a speed (``moving_obstacles``' ``cruise_speed_mm_s``): scans paired by
the chord such a mover drives, courses at least that fast, and a short chord read as a turn or a
stop. The three cases the option was built for (``docs/defences.md``): Labbots in a column paired
with each other's earlier positions, a pairing four times faster than a Labbot, and a Labbot that
stopped to turn between the scans and then drives off at full speed."""

from __future__ import annotations

import math

import numpy as np
import pytest
from safeembodai_plugins.validators.futures import WanderingFutures, WanderSettings
from safeembodai_plugins.validators.tracking import Blob, chord_share

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


def test_a_pairing_faster_than_max_obstacle_speed_gives_an_unknown_velocity():
    # only the leader was seen before: the one behind came out of nowhere (outside the old scan)
    before, now = [(3000.0, 2500.0, LABBOT_MM)], COLUMN["now"]
    blobs, _ = rule(cruise_speed_mm_s=150.0, max_obstacle_speed_mm_s=300.0).movers(context_for(LOOKING_UP, now, before))
    unknown = [b for b in blobs if b.velocity is None]
    assert len(blobs) == 2 and len(unknown) == 1


def mover(speed: float, span_s: float = 5.0) -> Blob:
    return Blob(centre=np.array([1000.0, 2000.0]), radius_mm=LABBOT_MM, velocity=np.array([speed, 0.0]), points=8,
                span_s=span_s)


def starts(futures: WanderingFutures, blob: Blob) -> np.ndarray:
    """Each course's heading off the chord in its first 0.1 s, degrees."""
    _, heading = futures.courses(blob, np.array([0.0, 0.1]))
    return np.degrees((heading[:, 0] + math.pi) % (2 * math.pi) - math.pi)


def test_a_chord_as_long_as_a_cruising_movers_keeps_every_course_around_it():
    futures = WanderingFutures(WanderSettings(count=256, cruise_speed_mm_s=150.0))
    full = mover(150.0 * chord_share(25.0, 5.0))
    assert futures.turned_share(full) == 0.0
    assert np.abs(starts(futures, full)).max() < 5 * 25.0 * math.sqrt(5.0 / 3.0)


def test_a_short_chord_fans_that_share_of_the_courses_at_the_cruising_speed():
    futures = WanderingFutures(WanderSettings(count=256, cruise_speed_mm_s=150.0))
    half = mover(0.5 * 150.0 * chord_share(25.0, 5.0))
    assert futures.turned_share(half) == pytest.approx(0.5)
    off = np.abs(starts(futures, half))
    assert 0.08 < np.mean(off > 120.0) < 0.26  # half fanned evenly, a third of those beyond 120 deg: 1/6
    where = futures.at(half, np.array([0.0, 1.0]))
    travelled = np.hypot(*(where[:, 1] - where[:, 0]).T)
    assert travelled[0] == pytest.approx(0.5 * 150.0 * chord_share(25.0, 5.0), rel=0.01)  # course 0: measured
    # the others cruise: a 1 s arc of a wandering course, its chord a little under 150 mm
    assert (travelled[1:] <= 150.0 + 1e-6).all() and np.median(travelled[1:]) > 145.0
    still = mover(10.0)  # 50 mm in 5 s: no direction at all
    assert futures.turned_share(still) == 1.0
    quadrants = np.floor((starts(futures, still)[1:] + 180.0) / 90.0)
    assert set(quadrants.tolist()) == {0.0, 1.0, 2.0, 3.0}


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
