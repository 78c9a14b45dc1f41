"""The sensors' shortcuts: the Labbots' rays cast only near a body, the camera without the balls it
cannot see, the LiDAR read without a loop per beam -- each reading what it read before."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_plugins.environments.pybullet_rooms import sensors as sensors_module
from safeembodai_plugins.environments.pybullet_rooms.scene import OBSTACLE_GROUP


def sensor_readings(env, rng, count: int) -> list[np.ndarray]:
    o = env.options
    readings = []
    for _ in range(count):
        labbots = rng.uniform(o.labbot_radius_mm + 5, o.room_mm - o.labbot_radius_mm - 5, (o.labbots, 2))
        if rng.random() < 0.5:  # a Labbot facing the robot from close by
            labbots[0] = env.xy + rng.uniform(300, 600) * np.array([1.0, 0.0])
        readings.append(env.labbot_sensors(labbots, rng.uniform(-180, 180, o.labbots), env.xy))
    return readings


@pytest.mark.parametrize("seed", [0, 7])
def test_labbot_sensors_read_what_casting_every_ray_reads(make_env, monkeypatch, seed):
    env = make_env("MO", labbots=6)
    env.reset(seed)
    fast = sensor_readings(env, np.random.default_rng(seed), 150)
    monkeypatch.setattr(sensors_module, "RAY_SLACK_MM", math.inf)  # every ray to Bullet
    slow = sensor_readings(env, np.random.default_rng(seed), 150)
    for ours, cast in zip(fast, slow):
        assert np.array_equal(ours, cast)
    assert any(np.isfinite(r).any() for r in fast) and any(np.isinf(r).all() for r in fast)


def poses(env, rng, count: int):
    """Anywhere in the room, and right beside each ball (balls at the lens's side or behind it)."""
    o = env.options
    for _ in range(count):
        yield rng.uniform(200, o.room_mm - 200, 2), rng.uniform(-180, 180)
    for ball in env.balls_xy:
        for side in (-90.0, 90.0, 180.0, 150.0, -150.0):
            away = rng.uniform(0, 360)
            xy = ball + (o.ball_radius_mm + o.robot_radius_mm + 20) * np.array([math.cos(math.radians(away)),
                                                                                 math.sin(math.radians(away))])
            yield xy, away + 180.0 + side  # the ball at the side of, or behind, the lens


@pytest.mark.parametrize("kind, seed", [("SO", 1), ("MO", 2)])
def test_the_camera_without_the_balls_out_of_view_draws_the_same_picture(make_env, kind, seed):
    env = make_env(kind)
    env.reset(seed)
    left_out = 0
    for xy, heading in poses(env, np.random.default_rng(seed), 12):
        hidden = env.sensors.balls_out_of_view(xy, heading)
        left_out += len(hidden)
        picture = env.sensors.camera(xy, heading)
        assert np.array_equal(picture, camera_with_every_ball(env, xy, heading))
    assert left_out > 0


def camera_with_every_ball(env, xy, heading):
    slack = sensors_module.VIEW_SLACK_MM
    sensors_module.VIEW_SLACK_MM = math.inf
    try:
        return env.sensors.camera(xy, heading)
    finally:
        sensors_module.VIEW_SLACK_MM = slack


def test_a_ball_left_out_of_one_picture_is_back_in_the_next(make_env):
    env = make_env("SO")
    env.reset(3)
    ball = np.asarray(env.balls_xy[0])
    behind = ball + np.array([400.0, 0.0])  # facing away from the ball: it is left out
    assert env.scene.balls[0] in env.sensors.balls_out_of_view(behind, 0.0)
    env.sensors.camera(behind, 0.0)
    facing = ball + np.array([900.0, 0.0])  # now facing it
    assert env.scene.balls[0] not in env.sensors.balls_out_of_view(facing, 180.0)
    assert np.array_equal(env.sensors.camera(facing, 180.0), camera_with_every_ball(env, facing, 180.0))


def test_lidar_reads_the_fraction_of_each_beam_that_hit(make_env):
    env = make_env("MO")
    env.reset(5)
    sensors, o = env.sensors, env.options
    ranges = sensors.lidar(env.xy, env.heading)
    angles = sensors.beam_angles + math.radians(env.heading)
    start = [[env.xy[0] / 1000.0, env.xy[1] / 1000.0, 0.1]] * len(angles)
    reach = o.lidar_max_range_mm / 1000.0
    end = [[s[0] + reach * math.cos(a), s[1] + reach * math.sin(a), 0.1] for s, a in zip(start, angles)]
    hits = env.scene.p.rayTestBatch(start, end, numThreads=1, collisionFilterMask=OBSTACLE_GROUP,
                                    physicsClientId=env.scene.client)
    expected = np.array([hit[2] if hit[0] >= 0 else np.inf for hit in hits]) * o.lidar_max_range_mm
    assert np.allclose(ranges, expected, rtol=0, atol=1e-9)
    assert np.isfinite(ranges).all()
