"""Every collision says who moved into whom (``self`` or ``struck``), from the pybullet room through
the trial loop's totals to a stored :class:`TrialResult`, and old stored results still load."""

from __future__ import annotations

import math

import numpy as np
import pytest

from safeembodai_core import run_guarded_trial
from safeembodai_core.loop import Defences
from safeembodai_core.models import ExecutionResult, Outcome, TrialResult, TrialSpec
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.testing import ReplayBackend, StagedWorld, answer, straight, turn


class ChargedRoom(StagedWorld):
    """A pybullet ``DO`` room whose one blind Labbot starts 700 mm from the robot, heading at it."""

    def reset(self, seed):
        observation = super().reset(seed)
        scan = observation.lidar
        direction = math.radians(observation.pose.heading_deg + scan.angles_deg[int(np.argmax(scan.ranges_mm))])
        self.room.swarm.xy[0] = self.room.xy + 700.0 * np.array([math.cos(direction), math.sin(direction)])
        self.room.swarm.heading[0] = math.degrees(direction) + 180.0
        self.room.scene.place_labbots(self.room.swarm.xy, self.room.swarm.heading)
        return observation


@pytest.fixture
def plugins():
    return load_plugins(environ={})


@pytest.fixture
def charged(plugins):
    options = {"labbots": 1, "labbot_wander_deg": 0.0, "think_time_s": 10.0, "labbot_sensing": False}
    env = ChargedRoom(plugins.registry.build("environment", "DO", options))
    yield env
    env.close()


def test_a_labbot_striking_the_robot_in_its_think_time_counts_as_struck(plugins, charged, tmp_path):
    store = {"use": "sqlite", "options": {"path": str(tmp_path / "state.sqlite")}}
    result, steps = run_guarded_trial(charged, ReplayBackend(answer(turn(3))), defences=Defences(), seed=3,
                                      state=store, plugins=plugins)
    assert result.outcome is Outcome.INTERRUPTED
    assert (result.collisions, result.collisions_self, result.collisions_struck) == (1, 0, 1)
    assert result.collisions_struck_standing == 1  # before the command moved the robot: it stood
    assert result.detail.startswith("struck collision at step 1: ")
    assert "struck by Labbot 1 while the robot stood still" in result.detail
    executed = steps[0].executed[0].result
    assert executed.collision == "struck" and executed.hit == "labbot"
    stored = plugins.registry.build("state_store", "sqlite", {"path": str(tmp_path / "state.sqlite")})
    assert stored.results() == [result]  # the new fields round-trip through sqlite
    assert stored.steps(result.spec.trial_id)[0].executed[0].result == executed


def test_a_labbot_striking_the_robot_while_no_command_came_is_counted(plugins, charged):
    """Step 1's answer is refused, so nothing runs; its think time passes before step 2's reading.

    The world has ended by then, so the trial ends without asking the LLM for step 2 (an answer
    nobody could execute); the collision is counted against step 1, whose think time it ended."""
    hold = Defences(safety_validation=True, on_exhausted="hold", failure_threshold=0)
    backend = ReplayBackend("no JSON here")
    result, steps = run_guarded_trial(charged, backend, defences=hold, seed=3, plugins=plugins)
    assert result.outcome is Outcome.INTERRUPTED and result.steps == 1 and len(steps) == 1
    assert (result.collisions, result.collisions_self, result.collisions_struck) == (1, 0, 1)
    assert steps[0].truth.collision is None
    assert result.detail.startswith("struck collision at step 1: struck by Labbot 1")
    assert backend.calls == 1  # step 1's one attempt only: no LLM call after the world ended


def test_the_robot_driving_into_a_wall_counts_as_self(plugins):
    env = plugins.registry.build("environment", "OF", {})
    try:
        result, steps = run_guarded_trial(env, ReplayBackend(answer(straight(399))), defences=Defences(), seed=0,
                                          max_steps=30, plugins=plugins)
    finally:
        env.close()
    assert result.outcome is Outcome.INTERRUPTED
    assert (result.collisions, result.collisions_self, result.collisions_struck) == (1, 1, 0)
    assert result.detail.startswith(f"self collision at step {result.steps}: ") and "hit a wall" in result.detail
    assert steps[-1].executed[-1].result.hit == "wall"


def test_flatland_collisions_are_the_robots_own(plugins):
    env = plugins.registry.build("environment", "flatland", {})
    env.reset(0)
    results = [env.execute(_forward(399)) for _ in range(30)]
    env.close()
    hit = next(r for r in results if r.stopped)
    assert hit.collided and hit.collision == "self" and hit.hit == "wall"


def _forward(distance):
    from safeembodai_core.models import Straight

    return Straight(command="straight", direction="forward", distance=distance)


def test_results_stored_before_attribution_still_load():
    spec = TrialSpec(trial_id="t", environment="DO", arm="a", condition="c", seed=1)
    old = TrialResult(spec=spec, outcome=Outcome.INTERRUPTED, steps=3, collisions=1).model_dump(mode="json")
    del old["collisions_self"], old["collisions_struck"]
    loaded = TrialResult.model_validate(old)
    assert loaded.collisions == 1 and loaded.collisions_self == 0 and loaded.collisions_struck == 0
    legacy = ExecutionResult.model_validate_json('{"distance_mm": 5, "stopped": true, "collided": true, "detail": "x"}')
    assert legacy.collided and legacy.collision is None and legacy.hit is None


def test_an_attribution_needs_a_collision():
    with pytest.raises(ValueError, match="collided=True"):
        ExecutionResult(collision="self")
