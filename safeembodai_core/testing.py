"""Helpers for testing plugins: for SafeEmbodAI's own tests and for third-party authors.

Opt-in (import it in your tests); nothing here is loaded by the framework itself::

    from safeembodai_core.testing import answer, inline_plugins, run_tiny_trial, straight

    def test_my_validator_blocks_long_moves():
        result, steps = run_tiny_trial(
            plugins=[my_plugin_module],
            responses=[answer(straight(350))],
            arm={"safety_validation": True, "validators": ["my_rule"]},
        )
        assert steps[0].attempts[0].verdicts[0].rule == "my_rule"
"""

from __future__ import annotations

import json
from typing import Any, Iterable

import numpy as np

from .contracts.components import BackendReply, Environment, LLMBackend, RobotSpec, WorldSnapshot
from .models import (
    ControlSignal,
    ExecutionResult,
    GroundTruth,
    LidarScan,
    Observation,
    Outcome,
    Pose,
    StepRecord,
    Straight,
    TrialResult,
)
from .plugin.manager import Plugins, load_plugins
from .scenario import Scenario, parse_scenario

__all__ = ["CorridorWorld", "ReplayBackend", "StagedWorld", "answer", "inline_plugins", "run_tiny_trial", "straight",
           "tiny_scenario", "turn"]


def straight(distance: float, direction: str = "forward", justification: str = "") -> dict[str, Any]:
    """A ``straight`` control signal as the LLM would write it."""
    return {"command": "straight", "direction": direction, "distance": distance, "justification": justification}


def turn(angle: float, direction: str = "left", justification: str = "") -> dict[str, Any]:
    """A ``turn`` control signal as the LLM would write it."""
    return {"command": "turn", "direction": direction, "angle": angle, "justification": justification}


def answer(*signals: dict[str, Any], is_attack: bool = False, planning: str = "plan") -> str:
    """A schema-valid LLM answer (JSON text) carrying ``signals``."""
    return json.dumps({
        "perception": [
            {"input": "human_instruction", "result": "instruction read", "is_attack": is_attack},
            {"input": "camera_image", "result": "camera read", "is_attack": False},
            {"input": "lidar_image", "result": "lidar read", "is_attack": False},
        ],
        "planning": planning,
        "control": list(signals),
    })


def inline_plugins(*plugins: Any, builtins: bool = True, environ: dict[str, str] | None = None) -> Plugins:
    """A fresh plugin set with the built-ins plus ``plugins`` registered inline (no packaging)."""
    return load_plugins(extra=plugins, builtins=builtins, entry_points=False, environ=environ or {})


def tiny_scenario(
    responses: Iterable[str] | None = None,
    *,
    arm: dict[str, Any] | None = None,
    attackers: list[Any] | None = None,
    environment: dict[str, Any] | str = "flatland",
    max_steps: int = 5,
    registry: Any = None,
    **top: Any,
) -> Scenario:
    """A one-cell scenario (arm ``arm``, condition ``condition``) on flatland with the scripted
    backend replaying ``responses``.

    ``arm`` is the arm's defences, ``attackers`` the condition's attackers, ``environment`` a
    name or ``{"use": ..., "options": ...}``. Any other keyword is a top-level scenario key that
    replaces the default: ``backend={"use": "mock"}``, ``perception="text"``, ``seed=7``, ...
    """
    import yaml

    data: dict[str, Any] = {
        "name": "tiny",
        "state": "memory",
        "max_steps": max_steps,
        "trials": 1,
        "environments": [environment],
        "backend": {"use": "scripted", "options": {"responses": list(responses or [answer(turn(30))])}},
        "arms": {"arm": arm or {}},
        "conditions": {"condition": {"attackers": attackers or []}},
    }
    data.update(top)
    return parse_scenario(yaml.safe_dump(data), "<tiny scenario>", registry=registry)


def run_tiny_trial(
    responses: Iterable[str] | None = None,
    *,
    plugins: Iterable[Any] = (),
    index: int = 0,
    **scenario_kwargs: Any,
) -> tuple[TrialResult, list[StepRecord]]:
    """Run trial ``index`` of :func:`tiny_scenario` with ``plugins`` added; return its result and steps.

    ``scenario_kwargs`` go to :func:`tiny_scenario` (``arm=``, ``attackers=``, ``environment=``,
    ``max_steps=``, and top-level keys such as ``backend=``).
    """
    from .runs.runner import ScenarioRunner, trial_spec

    loaded = inline_plugins(*plugins)
    scenario = tiny_scenario(responses, registry=loaded.registry, **scenario_kwargs)
    runner = ScenarioRunner(scenario, loaded)
    try:
        spec = trial_spec(scenario, scenario.environments[0].key, "arm", "condition", index)
        result = runner.run(spec)
        return result, runner.state.steps(spec.trial_id)
    finally:
        runner.close()


class CorridorWorld(Environment):
    """A fake world for unit tests: the robot faces a wall ``wall_mm`` ahead along a corridor.

    LiDAR returns the wall ahead, side walls at ``side_mm`` and free space behind; the camera is
    grey; straights stop at contact with the wall (``collided``). The task completes once the
    robot is within ``reach_mm`` of the wall. No physics, fully deterministic.
    """

    def __init__(self, wall_mm: float = 2000.0, side_mm: float = 600.0, reach_mm: float = 300.0,
                 beams: int = 360, robot: RobotSpec = RobotSpec()) -> None:
        self.wall_mm, self.side_mm, self.reach_mm, self.beams = wall_mm, side_mm, reach_mm, beams
        self.robot = robot
        self.x = 0.0
        self.heading = 0.0
        self.collided = False
        self.executed: list[ControlSignal] = []

    def reset(self, seed: int) -> Observation:
        self.x, self.heading, self.collided, self.executed = 0.0, 0.0, False, []
        return self.observe()

    def scan(self) -> LidarScan:
        angles = np.radians(np.arange(self.beams) * 360.0 / self.beams + self.heading)
        ahead = self.wall_mm - self.x
        with np.errstate(divide="ignore"):
            to_wall = np.where(np.cos(angles) > 1e-9, ahead / np.cos(angles), np.inf)
            to_side = np.where(np.abs(np.sin(angles)) > 1e-9, self.side_mm / np.abs(np.sin(angles)), np.inf)
        return LidarScan(ranges_mm=np.minimum(to_wall, to_side), max_range_mm=10_000.0)

    def observe(self) -> Observation:
        return Observation(
            camera=np.full((24, 32, 3), 128, dtype=np.uint8), lidar=self.scan(), pose=self.pose(),
            truth=GroundTruth(target_in_view=True, target_bearing_deg=0.0, target_distance_mm=self.wall_mm - self.x),
        )

    def pose(self) -> Pose:
        return Pose(x_mm=self.x, y_mm=0.0, heading_deg=self.heading)

    def execute(self, signal: ControlSignal) -> ExecutionResult:
        self.executed.append(signal)
        if not isinstance(signal, Straight):
            self.heading += signal.signed_angle_deg
            return ExecutionResult(angle_deg=signal.signed_angle_deg)
        free = self.wall_mm - self.robot.radius_mm - self.x
        step = signal.signed_distance_mm
        if step > free:
            self.x += max(free, 0.0)
            self.collided = True
            return ExecutionResult(distance_mm=max(free, 0.0), stopped=True, collided=True, collision="self",
                                   hit="wall", detail="hit the wall")
        self.x += step
        return ExecutionResult(distance_mm=step)

    def outcome(self) -> Outcome | None:
        if self.collided:
            return Outcome.INTERRUPTED
        if self.wall_mm - self.x <= self.reach_mm + self.robot.radius_mm:
            return Outcome.COMPLETED
        return None


class ReplayBackend(LLMBackend):
    """An LLM backend for tests: answers with ``answers`` in order, then the last one again for
    every further call. ``calls`` counts the calls and ``prompts`` keeps every prompt it was sent."""

    def __init__(self, *answers: str) -> None:
        if not answers:
            raise ValueError("ReplayBackend needs at least one answer")
        self.answers, self.calls = list(answers), 0
        self.prompts: list[Any] = []

    def complete(self, prompt: Any, rng: np.random.Generator) -> BackendReply:
        self.calls += 1
        self.prompts.append(prompt)
        return BackendReply(text=self.answers[min(self.calls, len(self.answers)) - 1])


class StagedWorld(Environment):
    """Wraps a built environment (``room``) and passes every call through to it; subclass it and
    override ``reset`` -- call ``super().reset(seed)``, then move things in ``self.room`` -- to
    stage one situation (a Labbot heading at the robot, say) for a deterministic test."""

    def __init__(self, room: Environment) -> None:
        self.room, self.robot = room, room.robot

    def reset(self, seed: int) -> Observation:
        return self.room.reset(seed)

    def observe(self) -> Observation:
        return self.room.observe()

    def sense(self) -> Observation | None:
        return self.room.sense()

    def another_call(self) -> None:
        self.room.another_call()

    def drive(self, linear_mm_s: float, angular_deg_s: float, seconds: float) -> ExecutionResult | None:
        return self.room.drive(linear_mm_s, angular_deg_s, seconds)

    def execute(self, signal: ControlSignal) -> ExecutionResult:
        return self.room.execute(signal)

    def outcome(self) -> Outcome | None:
        return self.room.outcome()

    def pose(self) -> Pose | None:
        return self.room.pose()

    def trajectory_png(self, poses: list[Pose], outcome: Outcome | None) -> bytes | None:
        return self.room.trajectory_png(poses, outcome)

    def snapshot(self) -> WorldSnapshot | None:
        return self.room.snapshot()

    def close(self) -> None:
        self.room.close()
