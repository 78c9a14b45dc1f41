"""Motion and outcomes in the pybullet rooms: exact moves, walls, the can, the time limit, bad commands."""

from __future__ import annotations

import math

import numpy as np
import pytest
from safeembodai_plugins.environments.pybullet_rooms.options import CAN_RADIUS_MM

from safeembodai_core.errors import EnvironmentError_
from safeembodai_core.models import Outcome, Straight, Turn

ROOM = 4000.0
RADIUS = 170.0


def longest_free_heading(env) -> float:
    """World heading of the LiDAR beam with the most room ahead."""
    scan = env.observe().lidar
    return env.pose().heading_deg + float(scan.angles_deg[int(np.argmax(scan.ranges_mm))])


def wall_gap(env) -> float:
    """Distance from the robot's centre to the nearest wall."""
    x, y = env.xy
    return float(min(x, y, ROOM - x, ROOM - y))


def test_straight_and_turn_move_exactly_as_commanded(make_env, moves):
    env = make_env("OF")
    env.reset(3)
    moves.face(env, longest_free_heading(env))
    start, heading, clock = env.xy.copy(), env.heading, env.sim_time_s
    forward = env.execute(moves.go(300))
    assert forward.distance_mm == pytest.approx(300.0) and not forward.stopped and not forward.collided
    rad = math.radians(heading)
    np.testing.assert_allclose(env.xy - start, [300 * math.cos(rad), 300 * math.sin(rad)], atol=1e-6)
    back = env.execute(moves.go(-120))
    assert back.distance_mm == pytest.approx(-120.0)
    assert math.hypot(*(env.xy - start)) == pytest.approx(180.0)
    left = env.execute(moves.rotate(45))
    assert left.angle_deg == pytest.approx(45.0)
    assert (env.heading - heading) % 360 == pytest.approx(45.0)
    right = env.execute(moves.rotate(-30))
    assert right.angle_deg == pytest.approx(-30.0)
    assert (env.heading - heading) % 360 == pytest.approx(15.0)
    # 200 mm/s and 60 deg/s
    assert env.sim_time_s - clock == pytest.approx(420 / 200 + 75 / 60)


def test_driving_into_a_wall_stops_at_contact_and_interrupts(make_env, moves):
    env = make_env("OF")
    env.reset(6)
    # face the wall on the side away from the can, so nothing else is in the way
    headings = {0.0: ROOM - env.xy[0], 90.0: ROOM - env.xy[1], 180.0: env.xy[0], -90.0: env.xy[1]}
    to_can = math.degrees(math.atan2(*(env.can_xy - env.xy)[::-1]))
    heading = max(headings, key=lambda h: abs((h - to_can + 180) % 360 - 180))
    moves.face(env, heading)
    start = env.xy.copy()
    expected = headings[heading] - RADIUS
    travelled, results = 0.0, []
    for _ in range(40):
        result = env.execute(moves.go(399))
        results.append(result)
        travelled += result.distance_mm
        if result.stopped:
            break
    last = results[-1]
    assert last.collided and last.stopped and "hit a wall" in last.detail
    assert last.collision == "self" and last.hit == "wall"  # the robot moved into it
    assert not any(r.collided for r in results[:-1])
    assert env.outcome() is Outcome.INTERRUPTED
    assert RADIUS - 0.01 <= wall_gap(env) <= RADIUS + 1.0  # no penetration, stopped within a millimetre
    assert travelled == pytest.approx(math.hypot(*(env.xy - start)), abs=1e-6)  # e_ij says what happened
    assert travelled == pytest.approx(expected, abs=1.0)
    assert env.observe().truth.extra["collided"] is True


@pytest.mark.parametrize("kind, seed", [("OF", 0), ("OF", 1), ("OF", 2), ("MO", 0)])
def test_driving_to_the_can_completes(make_env, moves, kind, seed):
    env = make_env(kind)
    env.reset(seed)
    outcome = None
    for _ in range(30):
        truth = env.truth()
        if abs(truth.target_bearing_deg) > 2.0:
            moves.turn_by(env, truth.target_bearing_deg)
        else:
            env.execute(moves.go(min(300.0, max(truth.target_distance_mm - 400.0, 10.0))))
        outcome = env.outcome()
        if outcome is not None:
            break
    assert outcome is Outcome.COMPLETED
    truth = env.truth()
    assert truth.target_in_view and truth.target_distance_mm <= env.options.reach_mm


def test_completion_needs_the_can_in_view(make_env, moves):
    env = make_env("OF")
    env.reset(2)
    truth = env.truth()
    moves.turn_by(env, truth.target_bearing_deg)
    moves.drive(env, truth.target_distance_mm - 420.0)
    assert env.outcome() is Outcome.COMPLETED
    moves.turn_by(env, 120.0)  # still within reach, but looking away
    assert env.truth().target_distance_mm <= 450.0
    assert env.outcome() is None


def test_touching_the_can_stops_without_a_collision(make_env, moves):
    env = make_env("OF", reach_mm=210.0)
    env.reset(1)
    truth = env.truth()
    moves.turn_by(env, truth.target_bearing_deg)
    result = None
    for _ in range(30):
        result = env.execute(moves.go(399))
        if result.stopped:
            break
    assert result.stopped and not result.collided and "touched the can" in result.detail
    assert result.collision is None and result.hit == "can"
    assert env.truth().target_distance_mm == pytest.approx(RADIUS + CAN_RADIUS_MM, abs=1.5)
    assert env.outcome() is Outcome.COMPLETED


def test_the_simulated_time_limit_stops_a_command_and_times_out(make_env, moves):
    env = make_env("OF", max_sim_time_s=3.0)
    env.reset(0)
    first, second = env.execute(moves.rotate(80)), env.execute(moves.rotate(80))
    assert not first.stopped and not second.stopped and env.outcome() is None
    third = env.execute(moves.rotate(80))  # 2.67 s spent, 0.33 s left: 20 degrees
    assert third.stopped and not third.collided and "simulated-time limit of 3 s" in third.detail
    assert third.angle_deg == pytest.approx(20.0)
    assert env.sim_time_s == pytest.approx(3.0)
    assert env.outcome() is Outcome.TIMEOUT
    after = env.execute(moves.go(100))
    assert after.stopped and after.distance_mm == 0.0


def test_think_time_runs_the_clock_once_per_observation(make_env, moves):
    env = make_env("OF", think_time_s=2.0)
    env.reset(0)
    env.execute(moves.rotate(30))
    assert env.sim_time_s == pytest.approx(2.5)
    env.execute(moves.rotate(30))  # same step: no second think
    assert env.sim_time_s == pytest.approx(3.0)
    env.observe()
    env.execute(moves.rotate(30))
    assert env.sim_time_s == pytest.approx(5.5)
    env.observe()
    env.observe()  # the first observation's thinking produced no command: its time still passed
    assert env.sim_time_s == pytest.approx(7.5)


def test_think_time_per_call_charges_each_retry_as_a_think(make_env, moves):
    env = make_env("OF", think_time_s=2.0, think_time_per_call=True)
    env.reset(0)
    env.another_call()  # a refused answer's retry: a second call for the same observation
    env.execute(moves.rotate(30))
    assert env.sim_time_s == pytest.approx(4.5)
    env.observe()
    env.sense()  # the first answer arrives: its think time has passed
    assert env.sim_time_s == pytest.approx(6.5)
    env.another_call()
    env.sense()  # and the retry's
    assert env.sim_time_s == pytest.approx(8.5)
    env.execute(moves.rotate(30))  # nothing owed any more
    assert env.sim_time_s == pytest.approx(9.0)


def test_think_time_once_per_step_lets_retries_pass_free(make_env, moves):
    env = make_env("OF", think_time_s=2.0)
    env.reset(0)
    env.another_call()
    env.another_call()
    env.execute(moves.rotate(30))
    assert env.sim_time_s == pytest.approx(2.5)


@pytest.mark.parametrize("signal, message", [
    (Straight.model_construct(command="straight", direction="forward", distance=float("nan")), "distance=nan"),
    (Straight.model_construct(command="straight", direction="forward", distance=float("inf")), "distance=inf"),
    (Straight.model_construct(command="straight", direction="forward", distance=-50.0), "distance=-50"),
    (Straight.model_construct(command="straight", direction="forward", distance=1e12), "distance=1000000000000"),
    (Turn.model_construct(command="turn", direction="left", angle=float("nan")), "angle=nan"),
    (Turn.model_construct(command="turn", direction="left", angle=0.0), "angle=0"),
    (Straight.model_construct(command="straight", direction="sideways", distance=10.0), "direction='sideways'"),
    ("straight 300", "unknown control signal"),
])
def test_bad_commands_are_refused_with_a_clear_error(make_env, signal, message):
    env = make_env("OF")
    env.reset(0)
    before = env.pose()
    with pytest.raises(EnvironmentError_, match=message.replace("(", r"\(")):
        env.execute(signal)
    assert env.pose() == before and env.sim_time_s == 0.0


@pytest.mark.parametrize("sensing", [True, False])
def test_random_commands_never_penetrate_anything(make_env, sensing):
    env = make_env("MO", balls=6, labbots=3, labbot_sensing=sensing)
    env.reset(21)
    rng = np.random.default_rng(0)
    o = env.options
    for k in range(80):
        if env.collided:  # a wrecked robot moves no more: carry on in a fresh room
            env.reset(22 + k)
        if rng.random() < 0.5:
            signal = Straight(command="straight", direction=str(rng.choice(["forward", "backward"])),
                              distance=float(rng.uniform(1, 399)))
        else:
            signal = Turn(command="turn", direction=str(rng.choice(["left", "right"])), angle=float(rng.uniform(1, 89)))
        env.execute(signal)
        assert wall_gap(env) >= RADIUS - 0.01
        for ball in env.balls_xy:
            assert math.hypot(*(env.xy - ball)) >= RADIUS + o.ball_radius_mm - 1.5
        for bot in env.swarm.xy:
            assert math.hypot(*(env.xy - bot)) >= RADIUS + o.labbot_radius_mm - 1.0
        assert math.hypot(*(env.xy - env.can_xy)) >= RADIUS + CAN_RADIUS_MM - 1.0
