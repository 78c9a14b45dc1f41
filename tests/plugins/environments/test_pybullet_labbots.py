"""Labbots: they move while the robot moves (and while the LLM thinks, if asked), avoid walls and
balls; blind ones can run into the robot (``struck``), sensing ones turn away from it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_core.models import Outcome


def travelled(track: list[np.ndarray]) -> np.ndarray:
    """Path length of each Labbot along its recorded track."""
    steps = np.diff(np.stack(track), axis=0)
    return np.hypot(steps[..., 0], steps[..., 1]).sum(axis=0)


def test_labbots_move_while_the_robot_moves(make_env, moves):
    env = make_env("DO")
    env.reset(4)
    start = env.swarm.xy.copy()
    env.execute(moves.rotate(60))  # one simulated second
    moved = np.hypot(*(env.swarm.xy - start).T)
    assert moved.max() > 50.0
    assert moved.max() <= 150.0 + 1e-6  # never faster than labbot_speed_mm_s
    # and pybullet sees them where they are: the LiDAR returns from a Labbot's new surface
    observation = env.observe()
    pose = observation.pose
    k = int(np.argmax(moved))
    bearing = math.degrees(math.atan2(*(env.swarm.xy[k] - env.xy)[::-1])) - pose.heading_deg
    beam = int(round(bearing)) % 360
    expected = math.hypot(*(env.swarm.xy[k] - env.xy)) - env.options.labbot_radius_mm
    assert observation.lidar.ranges_mm[beam] == pytest.approx(expected, abs=10.0)


def test_parked_labbots_stand_still(make_env, moves):
    parked = make_env("DO", labbot_speed_mm_s=0.0)
    parked.reset(4)
    start = parked.swarm.xy.copy()
    parked.execute(moves.rotate(60))
    np.testing.assert_array_equal(parked.swarm.xy, start)


def test_think_time_lets_the_world_move_before_the_first_command(make_env, moves):
    quick, slow = make_env("DO"), make_env("DO", think_time_s=4.0)
    quick.reset(8)
    slow.reset(8)
    quick.execute(moves.rotate(3))
    slow.execute(moves.rotate(3))
    assert travelled(slow.swarm.track).sum() > 10 * travelled(quick.swarm.track).sum()
    assert slow.sim_time_s == pytest.approx(4.05)


def test_labbots_keep_clear_of_walls_balls_the_can_and_each_other(make_env, moves):
    env = make_env("MO", balls=6, labbots=4, think_time_s=15.0)
    env.reset(12)
    o, r = env.options, env.options.labbot_radius_mm
    for _ in range(12):
        env.observe()
        env.execute(moves.rotate(5))
        xy = env.swarm.xy
        assert (xy > r).all() and (xy < o.room_mm - r).all()
        for ball in env.balls_xy:
            assert (np.hypot(*(xy - ball).T) >= r + o.ball_radius_mm).all()
        assert (np.hypot(*(xy - env.can_xy).T) >= r + 33.0).all()
        gaps = [math.hypot(*(xy[i] - xy[j])) for i in range(len(xy)) for j in range(i + 1, len(xy))]
        assert min(gaps) >= 2 * r
    steps = np.diff(np.stack(env.swarm.track), axis=0)
    assert (np.hypot(steps[..., 0], steps[..., 1]) == 0).any()  # some stood to turn away from something
    assert (travelled(env.swarm.track) > 1000.0).all()


def _labbot_charging_the_robot(make_env, seed=3, distance=700.0, **options):
    """A DO room with one Labbot ``distance`` mm from the robot, heading straight at it."""
    options = {"labbots": 1, "labbot_wander_deg": 0.0, "think_time_s": 10.0, **options}
    env = make_env("DO", **options)
    observation = env.reset(seed)
    scan = observation.lidar
    beam = int(np.argmax(scan.ranges_mm))  # the clearest direction
    direction = math.radians(observation.pose.heading_deg + scan.angles_deg[beam])
    unit = np.array([math.cos(direction), math.sin(direction)])
    env.swarm.xy[0] = env.xy + distance * unit
    env.swarm.heading[0] = math.degrees(direction) + 180.0
    env.scene.place_labbots(env.swarm.xy, env.swarm.heading)
    return env  # the next command starts with think time


def test_a_blind_labbot_running_into_the_standing_robot_interrupts_struck(make_env, moves):
    env = _labbot_charging_the_robot(make_env, labbot_sensing=False)
    result = env.execute(moves.rotate(3))
    assert result.collided and result.stopped
    assert result.collision == "struck" and result.hit == "labbot" and result.before_motion
    assert "struck by Labbot 1 while the robot stood still" in result.detail
    assert env.outcome() is Outcome.INTERRUPTED
    gap = math.hypot(*(env.swarm.xy[0] - env.xy)) - env.robot.radius_mm - env.options.labbot_radius_mm
    assert 0.0 <= gap <= 15.0  # it came right up to the robot, and no further
    again = env.execute(moves.go(100))  # a wrecked robot does not move on
    assert again.stopped and not again.collided and again.distance_mm == 0.0 and "not executed" in again.detail


def test_a_sensing_labbot_heading_at_the_standing_robot_turns_away(make_env, moves):
    env = _labbot_charging_the_robot(make_env)  # labbot_sensing is the default
    assert env.options.labbot_sensing
    result = env.execute(moves.rotate(3))
    assert not result.collided and result.collision is None
    assert env.outcome() is None
    gap = math.hypot(*(env.swarm.xy[0] - env.xy)) - env.robot.radius_mm - env.options.labbot_radius_mm
    assert gap >= env.options.labbot_sensor_range_mm - 10.0  # it stopped where its sensors first saw the robot
    env.observe()
    env.execute(moves.rotate(3))  # another 10 s of thinking: it has turned away and wanders on
    assert env.outcome() is None and travelled(env.swarm.track)[0] > 500.0


def test_the_labbot_sensors_see_the_robot_and_not_their_own_body(make_env):
    env = _labbot_charging_the_robot(make_env, distance=500.0)
    ranges = env.labbot_sensors(env.swarm.xy, env.swarm.heading, env.xy)
    expected = 500.0 - env.robot.radius_mm - env.options.labbot_radius_mm
    assert ranges.shape == (1, 5) and ranges[0, 0] == pytest.approx(expected, abs=2.0)
    env.swarm.heading[0] += 180.0  # facing away from the robot: nothing it could see
    far = env.labbot_sensors(env.swarm.xy, env.swarm.heading, env.xy)
    assert (far[0] > 10.0).all()


def test_a_labbot_running_into_the_turning_robot_is_struck_not_self(make_env, moves):
    env = _labbot_charging_the_robot(make_env, labbot_sensing=False, think_time_s=0.0, distance=600.0)
    results = [env.execute(moves.rotate(80)) for _ in range(4)]  # turning on the spot for over 5 s
    hit = next(r for r in results if r.collided)
    assert hit.collision == "struck" and "while the robot turned" in hit.detail


def test_the_robot_driving_into_a_parked_labbot_is_self(make_env, moves):
    env = _labbot_charging_the_robot(make_env, labbot_speed_mm_s=0.0, think_time_s=0.0, distance=900.0)
    moves.face(env, math.degrees(math.atan2(*(env.swarm.xy[0] - env.xy)[::-1])))
    results = moves.drive(env, 800.0)
    assert results[-1].collided and results[-1].collision == "self" and results[-1].hit == "labbot"
    assert "hit Labbot 1" in results[-1].detail


def test_a_labbot_striking_the_robot_while_no_command_came_is_reported_in_the_next_truth(make_env, moves):
    env = _labbot_charging_the_robot(make_env, labbot_sensing=False)
    observation = env.observe()  # the last observation led to no command: its 10 s of thinking pass now
    truth = observation.truth
    assert truth.extra["collided"] is True and truth.collision == "struck" and truth.hit == "labbot"
    assert "struck by Labbot 1 while the robot stood still" in truth.collision_detail
    assert env.observe().truth.collision is None  # reported once
    assert env.outcome() is Outcome.INTERRUPTED
    assert not env.execute(moves.rotate(3)).collided  # not executed, not a second collision


def test_blind_labbots_told_to_avoid_the_robot_do_not_hit_it(make_env, moves):
    env = _labbot_charging_the_robot(make_env, labbot_sensing=False, labbots_avoid_robot=True)
    result = env.execute(moves.rotate(3))
    assert not result.collided
    assert env.outcome() is None
    assert travelled(env.swarm.track)[0] > 300.0


def test_sensing_labbots_are_deterministic_for_a_seed(registry, moves):
    """The same seed and commands give the same Labbots, with the robot driving among them."""

    def run():
        env = registry.build("environment", "MO", {"think_time_s": 2.0, "labbots": 3})
        try:
            env.reset(5)
            for k in range(12):
                env.execute(moves.go(250.0) if k % 3 else moves.rotate(70.0))
                env.observe()
            return env.sim_time_s, np.stack(env.swarm.track), env.pose()
        finally:
            env.close()

    first, second = run(), run()
    assert first[0] == second[0] and first[2] == second[2]
    assert np.array_equal(first[1], second[1])


def test_labbots_depend_on_simulated_time_only_not_on_how_commands_are_split():
    """Two arms that spend the same simulated time meet the same blind Labbots (paired comparison;
    sensing Labbots react to the robot, so the pairing holds only while the robots' paths agree)."""
    import numpy as np

    from safeembodai_core.models import Turn
    from safeembodai_core.plugin.manager import load_plugins

    registry = load_plugins(environ={}).registry

    def labbots_after(*signals):
        env = registry.build("environment", "DO", {"labbot_sensing": False})
        try:
            env.reset(7)
            for signal in signals:
                env.execute(signal)
            return env.sim_time_s, env.swarm.xy.copy(), env.swarm.heading.copy()
        finally:
            env.close()

    one = labbots_after(Turn(command="turn", direction="left", angle=31.5))
    split = labbots_after(Turn(command="turn", direction="left", angle=30),
                          Turn(command="turn", direction="left", angle=1.5))
    assert one[0] == pytest.approx(split[0])
    assert np.array_equal(one[1], split[1]) and np.array_equal(one[2], split[2])


def test_the_sensors_are_skipped_only_when_they_would_read_nothing(make_env, moves):
    """A tick casts the Labbots' sensors only when something lies near one of them; when the cheap
    distance bound says nothing does, the real sensors, cast anyway, read nothing on every ray."""
    env = make_env("DO", think_time_s=5)
    skipped = cast = 0
    for seed in range(6):
        env.reset(seed)
        for _ in range(60):
            env.execute(moves.go(100) if seed % 2 else moves.rotate(20))
            swarm = env.swarm
            readings = env.labbot_sensors(swarm.xy, swarm.heading, env.xy)
            if swarm._out_of_reach(env.xy):
                skipped += 1
                assert np.isinf(readings).all(), readings
            else:
                cast += 1
            if env.outcome() is not None:
                break
    assert skipped >= 20 and cast >= 20  # both branches were exercised
