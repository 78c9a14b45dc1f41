"""Registration and options of the pybullet rooms: names, defaults, bad input, light import."""

from __future__ import annotations

import subprocess
import sys

import pytest

from safeembodai_core.plugin.registry import ComponentOptionsError

KINDS = ("OF", "SO", "DO", "MO")


def test_the_four_rooms_are_registered_by_the_builtin_plugin(registry):
    for kind in KINDS:
        info = registry.get("environment", kind)
        assert info.plugin == "pybullet_rooms"
        assert "pybullet" in info.description


@pytest.mark.parametrize("kind, balls, labbots", [("OF", 0, 0), ("SO", 4, 0), ("DO", 0, 3), ("MO", 3, 2)])
def test_each_room_holds_its_obstacles_by_default(make_env, kind, balls, labbots):
    env = make_env(kind)
    assert len(env.scene.balls) == balls
    assert len(env.scene.labbots) == labbots
    assert env.robot.radius_mm == 170.0


@pytest.mark.parametrize("kind, key", [("OF", "balls"), ("OF", "labbots"), ("SO", "labbots"), ("DO", "balls")])
def test_a_room_refuses_obstacles_it_does_not_have(registry, kind, key):
    with pytest.raises(ComponentOptionsError, match=key):
        registry.validate_options("environment", kind, {key: 2})


@pytest.mark.parametrize("options, key", [
    ({"room_mm": -4000}, "room_mm"),
    ({"room_mm": 100_000}, "room_mm"),
    ({"robot_speed_mm_s": 0}, "robot_speed_mm_s"),
    ({"lidar_beams": 10}, "lidar_beams"),
    ({"camera_fov_deg": 180}, "camera_fov_deg"),
    ({"max_sim_time_s": -1}, "max_sim_time_s"),
    ({"think_time_s": -0.5}, "think_time_s"),
    ({"balls": 0}, "balls"),
    ({"labbot_speed_mm_s": -1}, "labbot_speed_mm_s"),
    ({"colour": "red"}, "colour"),
    ({"room_mm": float("nan")}, "room_mm"),
    ({"min_start_distance_mm": float("inf")}, "min_start_distance_mm"),
    ({"reach_mm": float("inf")}, "reach_mm"),
])
def test_out_of_range_options_name_the_option(registry, options, key):
    with pytest.raises(ComponentOptionsError) as caught:
        registry.validate_options("environment", "MO", options)
    assert key in str(caught.value)
    assert "'MO'" in str(caught.value)


def test_more_obstacles_than_fit_is_refused_before_any_physics(registry):
    with pytest.raises(ComponentOptionsError) as caught:
        registry.build("environment", "SO", {"balls": 40})
    message = str(caught.value)
    assert "balls=40" in message and "room_mm=4000" in message and "too many obstacles" in message
    # a bigger room takes them
    registry.validate_options("environment", "SO", {"balls": 40, "room_mm": 8000})


def test_mixed_room_counts_balls_and_labbots_together(registry):
    registry.validate_options("environment", "MO", {"balls": 10, "labbots": 5})
    with pytest.raises(ComponentOptionsError, match="balls=10 and labbots=12"):
        registry.validate_options("environment", "MO", {"balls": 10, "labbots": 12})


def test_a_reach_the_robot_cannot_get_within_is_refused(registry):
    with pytest.raises(ComponentOptionsError, match="reach_mm=150"):
        registry.validate_options("environment", "OF", {"reach_mm": 150})


def test_a_start_distance_the_room_cannot_offer_is_refused(registry):
    with pytest.raises(ComponentOptionsError, match="min_start_distance_mm=3500"):
        registry.validate_options("environment", "OF", {"min_start_distance_mm": 3500})
    small = registry.validate_options("environment", "OF", {"room_mm": 1500})
    assert small.start_distance == 900.0  # the default shrinks with the room


def test_the_plugin_module_does_not_import_pybullet():
    code = ("import sys, safeembodai_plugins.environments.pybullet_rooms as m; "
            "m.register_environments(lambda *a, **k: None); "
            "print(sorted(k for k in ('pybullet', 'pybullet_data', 'cv2', 'matplotlib') if k in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_start_distance_below_what_the_bodies_need_is_refused_not_raised(registry):
    """A user's value is honoured or refused with the reason, never changed silently."""
    with pytest.raises(ComponentOptionsError, match="min_start_distance_mm=100 is less than"):
        registry.validate_options("environment", "OF", {"min_start_distance_mm": 100})
    honoured = registry.validate_options("environment", "OF", {"min_start_distance_mm": 600})
    assert honoured.start_distance == 600.0
