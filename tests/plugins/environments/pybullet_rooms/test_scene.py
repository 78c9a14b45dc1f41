"""The scene's contact checks and placements: the shortcuts answer what Bullet answers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_plugins.environments.pybullet_rooms import scene as scene_module


def wander(env, rng, steps: int):
    """Random robot and Labbot placements, often touching: the contacts each gives."""
    scene, o = env.scene, env.options
    found = []
    for _ in range(steps):
        if rng.random() < 0.5:  # next to a body, or anywhere
            anchor = rng.choice(len(env.swarm.xy) + 1)
            centre = env.can_xy if anchor == len(env.swarm.xy) else env.swarm.xy[anchor]
            angle = rng.uniform(0, 2 * math.pi)
            reach = o.robot_radius_mm + rng.uniform(0, 250)
            robot = centre + reach * np.array([math.cos(angle), math.sin(angle)])
        else:
            robot = rng.uniform(o.robot_radius_mm - 30, o.room_mm - o.robot_radius_mm + 30, 2)
        scene.place_robot(robot, rng.uniform(-180, 180))
        labbots = env.swarm.xy + rng.normal(0, 150, env.swarm.xy.shape)
        scene.place_labbots(labbots, rng.uniform(-180, 180, len(labbots)))
        found.append(scene.contacts())
    return found


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_contacts_with_the_shortcut_are_bullets_own(make_env, monkeypatch, seed):
    fast = make_env("MO")
    fast.reset(seed)
    with_shortcut = wander(fast, np.random.default_rng(seed), 300)
    monkeypatch.setattr(scene_module, "CLEAR_MM", math.inf)  # every check asked of Bullet
    slow = make_env("MO")
    slow.reset(seed)
    assert wander(slow, np.random.default_rng(seed), 300) == with_shortcut
    assert any(with_shortcut) and not all(with_shortcut)  # both answers were tried


def test_the_clearance_is_a_lower_bound_bullet_agrees_with(make_env, monkeypatch):
    monkeypatch.setattr(scene_module, "CLEAR_MM", math.inf)
    env = make_env("MO")
    env.reset(4)
    rng = np.random.default_rng(4)
    for _ in range(200):
        wander(env, rng, 1)  # a random placement
        gap, touching = env.scene.clearance(), env.scene.contacts()
        assert not (gap > 0 and touching), (gap, touching)


def test_a_placement_reaches_bullet_at_its_next_read(make_env):
    env = make_env("MO")
    env.reset(0)
    scene = env.scene
    scene.place_robot(np.array([1000.0, 1200.0]), 30.0)
    scene.place_robot(np.array([1500.0, 900.0]), 45.0)  # the last placement is the one Bullet gets
    scene.flush()
    position, orientation = scene.p.getBasePositionAndOrientation(scene.robot, physicsClientId=scene.client)
    assert position == pytest.approx((1.5, 0.9, 0.1))
    assert orientation == pytest.approx(scene_module.yaw_quaternion(45.0))
    assert scene.robot_xy == (1500.0, 900.0)


def test_a_new_trial_asks_bullet_before_trusting_an_empty_answer(make_env):
    env = make_env("MO")
    env.reset(0)
    env.scene._clean = True  # as after a far check in the last trial
    env.reset(1)
    assert env.scene._clean is False  # the first check of the new trial goes to Bullet
