"""Sensors of the pybullet rooms: shapes, units and conventions of camera, LiDAR and ground truth."""

from __future__ import annotations

import math

import numpy as np
import pytest
from safeembodai_plugins.environments.pybullet_rooms.layout import (
    HIDDEN_MARGIN_DEG,
    draw_layout,
)
from safeembodai_plugins.environments.pybullet_rooms.options import CAN_RADIUS_MM
from safeembodai_plugins.perception.describe import find_red_target

from safeembodai_core.errors import EnvironmentError_

KINDS = ("OF", "SO", "DO", "MO")


def wall_distance(x: float, y: float, angles_rad: np.ndarray, room: float) -> np.ndarray:
    """Distance from (x, y) along each angle to the walls of a [0, room] square."""
    dx, dy = np.cos(angles_rad), np.sin(angles_rad)
    with np.errstate(divide="ignore"):
        tx = np.where(dx > 1e-12, (room - x) / dx, np.where(dx < -1e-12, -x / dx, np.inf))
        ty = np.where(dy > 1e-12, (room - y) / dy, np.where(dy < -1e-12, -y / dy, np.inf))
    return np.minimum(tx, ty)


def misses_disc(x, y, angles_rad, cx, cy, radius) -> np.ndarray:
    """True for rays from (x, y) that pass more than ``radius`` from (cx, cy)."""
    rx, ry = cx - x, cy - y
    along = rx * np.cos(angles_rad) + ry * np.sin(angles_rad)
    across = np.abs(-rx * np.sin(angles_rad) + ry * np.cos(angles_rad))
    return (across > radius) | (along < 0)


@pytest.mark.parametrize("kind", KINDS)
def test_every_room_observes_a_qvga_image_a_360_beam_scan_pose_and_truth(make_env, kind):
    env = make_env(kind)
    observation = env.reset(4)
    assert observation.camera.shape == (240, 320, 3) and observation.camera.dtype == np.uint8
    assert observation.lidar.beam_count == 360 and observation.lidar.max_range_mm == 6000.0
    assert np.isfinite(observation.lidar.ranges_mm).all()  # a 4 m room is within range everywhere
    assert observation.lidar.ranges_mm.min() > env.robot.radius_mm  # measured from the centre, no overlap
    assert observation.pose == env.pose()
    assert 0 < observation.pose.x_mm < 4000 and 0 < observation.pose.y_mm < 4000
    assert observation.truth.target_distance_mm >= 1200.0
    assert observation.sim_time_s == 0.0


def test_lidar_beam_k_points_k_degrees_ccw_and_measures_millimetres_from_the_centre(make_env):
    env = make_env("OF")
    observation = env.reset(9)
    pose = observation.pose
    angles = np.radians(pose.heading_deg + np.arange(360))
    expected = wall_distance(pose.x_mm, pose.y_mm, angles, 4000.0)
    clear = misses_disc(pose.x_mm, pose.y_mm, angles, *env.can_xy, CAN_RADIUS_MM + 5)
    assert clear.sum() > 340
    np.testing.assert_allclose(observation.lidar.ranges_mm[clear], expected[clear], atol=1.0)
    # the can's beams return short of the wall behind it
    blocked = ~misses_disc(pose.x_mm, pose.y_mm, angles, *env.can_xy, CAN_RADIUS_MM - 5)
    assert blocked.any() and (observation.lidar.ranges_mm[blocked] < expected[blocked] - 100).all()


def test_beams_without_a_return_within_range_are_inf(make_env):
    env = make_env("OF", lidar_max_range_mm=800.0)
    observation = env.reset(9)
    pose = observation.pose
    expected = wall_distance(pose.x_mm, pose.y_mm, np.radians(pose.heading_deg + np.arange(360)), 4000.0)
    ranges = observation.lidar.ranges_mm
    assert np.isposinf(ranges[expected > 810]).all()
    assert np.isfinite(ranges[expected < 790]).all()


def test_lidar_sees_balls_and_labbots_in_mixed_room(make_env):
    env = make_env("MO")
    observation = env.reset(2)
    pose = observation.pose
    angles = np.radians(pose.heading_deg + np.arange(360))
    walls = wall_distance(pose.x_mm, pose.y_mm, angles, 4000.0)
    exact = 0
    bodies = [(b, env.options.ball_radius_mm) for b in env.balls_xy] + [(bot, 120.0) for bot in env.swarm.xy]
    for xy, radius in bodies:
        towards = ~misses_disc(pose.x_mm, pose.y_mm, angles, *xy, radius * 0.5)
        surface = math.hypot(xy[0] - pose.x_mm, xy[1] - pose.y_mm) - radius
        nearest = observation.lidar.ranges_mm[towards].min()
        assert (observation.lidar.ranges_mm[towards] < walls[towards]).all()
        assert nearest <= surface + 15.0  # this body, or one hiding it
        exact += abs(nearest - surface) < 15.0
    assert exact >= len(bodies) - 1  # at most one is hidden behind another in this room


def test_the_can_starts_out_of_view_and_shows_red_once_the_robot_faces_it(make_env, moves):
    env = make_env("OF")
    for seed in range(3):
        observation = env.reset(seed)
        assert not observation.truth.target_in_view
        assert abs(observation.truth.target_bearing_deg) > 30.0 + HIDDEN_MARGIN_DEG
        assert not find_red_target(observation.camera).seen
        moves.turn_by(env, observation.truth.target_bearing_deg)
        seen = env.observe()
        assert seen.truth.target_in_view and abs(seen.truth.target_bearing_deg) < 0.5
        sighting = find_red_target(seen.camera)
        assert sighting.seen and abs(sighting.bearing_deg) < 2.0


def test_bearing_is_counter_clockwise_positive_and_matches_the_image(make_env, moves):
    env = make_env("OF")
    observation = env.reset(1)
    moves.turn_by(env, observation.truth.target_bearing_deg - 15.0)  # can 15 degrees to the left
    left = env.observe()
    assert left.truth.target_bearing_deg == pytest.approx(15.0, abs=0.01)
    assert left.truth.target_in_view and find_red_target(left.camera).bearing_deg > 10.0
    moves.turn_by(env, 30.0)  # now 15 degrees to the right
    right = env.observe()
    assert right.truth.target_bearing_deg == pytest.approx(-15.0, abs=0.01)
    assert find_red_target(right.camera).bearing_deg < -10.0
    moves.turn_by(env, -55.0)  # 40 degrees left: outside the 60-degree field of view
    outside = env.observe()
    assert not outside.truth.target_in_view and not find_red_target(outside.camera).seen


def test_a_ball_between_robot_and_can_hides_it(make_env, moves):
    env = make_env("SO", balls=1)
    env.reset(5)
    moves.face(env, math.degrees(math.atan2(*(env.can_xy - env.xy)[::-1])))
    assert env.observe().truth.target_in_view
    middle = (env.xy + env.can_xy) / 2
    env.balls_xy[0] = middle
    env.scene.place_statics(env.can_xy, env.balls_xy)
    hidden = env.observe()
    assert not hidden.truth.target_in_view
    assert not find_red_target(hidden.camera).seen


def test_camera_size_and_field_of_view_are_options(make_env):
    env = make_env("OF", camera_width=160, camera_height=120, camera_fov_deg=90.0, lidar_beams=720)
    observation = env.reset(0)
    assert observation.camera.shape == (120, 160, 3)
    assert observation.lidar.beam_count == 720


def test_layouts_never_overlap_and_keep_the_passage(registry):
    options = registry.validate_options("environment", "MO", {"balls": 8, "labbots": 4})
    for seed in range(25):
        layout = draw_layout(options, np.random.default_rng(seed))
        bodies = ([(layout.robot_xy, 170.0), (layout.can_xy, CAN_RADIUS_MM)]
                  + [(ball, options.ball_radius_mm) for ball in layout.balls_xy]
                  + [(bot, 120.0) for bot in layout.labbots_xy])
        for i, (a, ra) in enumerate(bodies):
            assert ra < a[0] < 4000 - ra and ra < a[1] < 4000 - ra
            for b, rb in bodies[i + 1:]:
                assert math.hypot(*(a - b)) >= ra + rb + options.passage - 1e-6


def test_using_an_environment_before_reset_or_after_close_is_a_clear_error(make_env):
    env = make_env("OF")
    with pytest.raises(EnvironmentError_, match="reset"):
        env.observe()
    env.reset(0)
    env.close()
    with pytest.raises(EnvironmentError_, match="closed"):
        env.reset(0)
