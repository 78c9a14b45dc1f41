"""``moving_obstacles`` in a pybullet ``DO`` room: a blind Labbot on a known course crosses the
robot's path during the think time. ``lidar_clearance`` alone accepts the plan (the Labbot is
outside its ±30 deg sector at scan time) and the robot drives into it (``self``); with
``moving_obstacles`` the plan is refused until the Labbot has passed."""

from __future__ import annotations

import numpy as np
import pytest

from safeembodai_core import run_guarded_trial
from safeembodai_core.loop import Defences
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.testing import ReplayBackend, StagedWorld, answer, straight, turn

THINK_S = 5.0


class CrossingRoom(StagedWorld):
    """A 6 m ``DO`` room: the robot at (1000, 2000) facing +x, one blind Labbot driving -y along
    x = 1800 at 150 mm/s, timed to stand across the robot's path when a plan of step 3 gets there."""

    def reset(self, seed):
        super().reset(seed)
        room = self.room
        room.xy, room.heading = np.array([1000.0, 2000.0]), 0.0
        room.can_xy = np.array([5600.0, 400.0])
        room.swarm.xy[0], room.swarm.heading[0] = (1800.0, 4632.0), -90.0
        room.swarm._statics = [(5600.0, 400.0, 33.0)]
        room.scene.place_statics(room.can_xy, room.balls_xy)
        room._sync()
        room._thinks = 0  # nothing owed: the reading below is the step's observation, as after reset
        return room.observe()


@pytest.fixture
def plugins():
    return load_plugins(environ={})


@pytest.fixture
def crossing(plugins):
    options = {"room_mm": 6000.0, "labbots": 1, "labbot_wander_deg": 0.0, "think_time_s": THINK_S,
               "labbot_sensing": False}
    env = CrossingRoom(plugins.registry.build("environment", "DO", options))
    yield env
    env.close()


PLAN = (answer(turn(2, "left")), answer(turn(2, "right")), answer(straight(399), straight(399), straight(399)))


def _run(env, plugins, validators):
    defences = Defences(safety_validation=True, validators=validators, failure_threshold=0, on_exhausted="hold")
    return run_guarded_trial(env, ReplayBackend(*PLAN), defences=defences, seed=1, max_steps=5, plugins=plugins)


def test_lidar_clearance_alone_drives_into_the_crossing_labbot(plugins, crossing):
    result, steps = _run(crossing, plugins, ["command_limits", "lidar_clearance"])
    assert result.collisions_self == 1 and result.collisions_struck == 0
    assert steps[2].accepted and steps[-1].executed[-1].result.hit == "labbot"


def test_moving_obstacles_refuses_the_plan_that_would_meet_it(plugins, crossing):
    rule = {"use": "moving_obstacles", "options": {"think_time_s": THINK_S}}
    result, steps = _run(crossing, plugins, ["command_limits", "lidar_clearance", rule])
    assert result.collisions_self == 0
    refused = [v for v in steps[2].attempts[0].verdicts if v.rule == "moving_obstacles" and not v.valid]
    assert refused and "a moving obstacle" in refused[0].reason and "may be in the way" in refused[0].reason
    assert "(heading -9" in refused[0].reason  # crossing to the robot's right
