"""``moving_obstacles`` with ``walls``: predicted courses turn where the step's scan shows something
standing, instead of passing through it (issue 21: fast movers turn at walls and come back).
Synthetic scans of the 6 m square room of tests/support/mover_scenes.py."""

from __future__ import annotations


import numpy as np

from safeembodai_plugins.validators.moving.futures import WanderingFutures, WanderSettings
from safeembodai_plugins.validators.moving.tracking import Blob
from safeembodai_plugins.validators.moving.walls import Walls

from mover_scenes import LABBOT_MM, ROBOT, ROOM_MM, go, history_context, refused, scan_from
from mover_scenes import learned_rule as rule


def room_walls() -> Walls:
    """The room's walls as the robot at ROBOT sees them (nothing else in the room)."""
    return Walls.seen(scan_from(ROBOT, []), ROBOT, [])


def test_a_disc_is_blocked_near_a_standing_return_and_clear_away_from_it():
    walls = room_walls()
    near = np.array([[3000.0, ROOM_MM - 100.0], [60.0, 3000.0]])
    clear = np.array([[3000.0, 3000.0], [3000.0, ROOM_MM - 400.0]])
    assert walls.blocked(near, LABBOT_MM).all()
    assert not walls.blocked(clear, LABBOT_MM).any()
    assert not Walls(np.zeros((0, 2))).blocked(near, LABBOT_MM).any()  # nothing seen: nothing blocks


def test_a_movers_own_returns_are_not_walls():
    mover = Blob(centre=np.array([3000.0, 3000.0]), radius_mm=LABBOT_MM, velocity=np.array([0.0, 300.0]), points=5)
    scan = scan_from(ROBOT, [(3000.0, 3000.0, LABBOT_MM)])
    assert Walls.seen(scan, ROBOT, []).blocked(np.array([[3000.0, 3000.0]]), LABBOT_MM).all()
    assert not Walls.seen(scan, ROBOT, [mover]).blocked(np.array([[3000.0, 3000.0]]), LABBOT_MM).any()


def test_courses_turn_at_a_wall_instead_of_passing_through_it():
    """A mover 500 mm from the far wall, heading for it at 400 mm/s: drawn freely, its courses
    leave the room; turned at the wall, every one stays inside and many come back."""
    futures = WanderingFutures(WanderSettings(wander_deg=10.0, count=128, step_s=0.1, seed=3))
    mover = Blob(centre=np.array([3000.0, ROOM_MM - 500.0]), radius_mm=LABBOT_MM, velocity=np.array([0.0, 400.0]),
                 points=5, span_s=5.0)
    times = np.arange(0.0, 10.0, 0.1)
    free = futures.at(mover, times)
    assert (free[..., 1] > ROOM_MM).any()
    turned = futures.at(mover, times, room_walls())
    assert (turned[..., 1] < ROOM_MM - LABBOT_MM).all() and (turned[..., 0] > LABBOT_MM).all()
    assert (turned[..., 0] < ROOM_MM - LABBOT_MM).all()
    assert (turned[:, -1, 1] < ROOM_MM - 2000.0).mean() > 0.25  # back into the room
    # before the wall, the courses are the free ones; the same check gives the same courses
    assert np.array_equal(turned[:, :5], free[:, :5])
    again = WanderingFutures(WanderSettings(wander_deg=10.0, count=128, step_s=0.1, seed=3))
    assert np.array_equal(again.at(mover, times[:40], room_walls()), turned[:, :40])
    # every stepped point, the last included, keeps the disc off the wall
    grid, _, _ = futures._walled_grid(mover, 64, room_walls())
    assert (grid[..., 1] < ROOM_MM - LABBOT_MM).all() and grid.shape[1] == 65


def test_a_mover_that_turns_at_a_wall_can_refuse_a_straight_its_free_courses_never_meet():
    """A Labbot at 400 mm/s heading away from the robot's line, towards the wall behind it: its
    free courses leave the room, so the robot's 1.17 m forward passes; turning at the wall, some
    come back across the robot's line while it drives there."""
    positions = [(2200.0, 4500.0 - 400.0 * 6.0 * (2 - i)) for i in range(3)]
    context = history_context(ROBOT, positions, 6.0)
    plan = [go(390), go(390), go(390)]
    assert not refused(plan, context, rule(max_obstacle_speed_mm_s=600.0))
    [reason] = refused(plan, history_context(ROBOT, positions, 6.0), rule(max_obstacle_speed_mm_s=600.0, walls=True))
    assert "moving obstacle" in reason


def test_a_hostile_scan_cannot_make_the_walls_grid_huge():
    """Returns at 10^12 mm (finite: a LidarScan allows them) are beyond any wall's reach: the grid
    stays the room's size, and the rule judges on."""
    from safeembodai_core.models import LidarScan

    scan = scan_from(ROBOT, [])
    ranges = scan.ranges_mm.copy()
    ranges[::7] = 1e12
    hostile = LidarScan(ranges, 1e13)
    walls = Walls.seen(hostile, ROBOT, [])
    assert walls.occupied.size <= (2 * 20_000 // 50 + 1) ** 2 and walls.count > 0
    positions = [(2200.0, 4500.0 - 400.0 * 6.0 * (2 - i)) for i in range(3)]
    context = history_context(ROBOT, positions, 6.0)
    context = type(context)(scan=hostile, start_pose=context.start_pose, sim_time_s=context.sim_time_s,
                            history=context.history)
    refused([go(390)], context, rule(max_obstacle_speed_mm_s=600.0, walls=True))  # judged, no MemoryError
