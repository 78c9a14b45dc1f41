"""What a trial looked like from inside, for exported bags: what each step's decision read, and the
world around every command.

:class:`TrialCapture` wraps a trial's environment and perception (:meth:`TrialCapture.wrap`) and
keeps, in the order they happened, an event per observation (the world's snapshot and the robot's
pose when the sensors were read), per step's perception (the scan as the rules read it -- after any
sensor attack -- and the images and texts the LLM was shown) and per executed command (the world
before and after it, and its result). Nothing is changed on the way through: the wrapped components
answer exactly as the originals. The step records themselves come from the state store.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..contracts.components import Environment, Perception, PromptBuilder, WorldSnapshot
from ..models import ControlSignal, ExecutionResult, Modalities, Observation, Pose, Prompt
from ..models.observation import ImagePart, LidarScan
from ..contracts.robot import RobotSpec


@dataclass(frozen=True)
class Observed:
    """The sensors were read: the world then, and the robot's true pose."""

    world: WorldSnapshot | None
    pose: Pose | None
    sim_time_s: float


@dataclass(frozen=True)
class Seen:
    """Step ``step``'s decision read this: the step's scan (as attackers left it), the images and
    texts the LLM saw. With an arm's ``fresh_scan`` the rules judged a later reading, which this
    capture records only as an :class:`Observed` event (the world and pose then), not its scan."""

    step: int
    scan: LidarScan | None
    images: dict[str, ImagePart]
    texts: dict[str, str]


@dataclass(frozen=True)
class Executed:
    """Step ``step`` executed ``signal``: the world before and after, and what it did."""

    step: int
    signal: ControlSignal
    result: ExecutionResult
    before: WorldSnapshot | None
    after: WorldSnapshot | None
    pose_after: Pose | None


Event = Observed | Seen | Executed


@dataclass
class TrialCapture:
    """The events of one trial, in order (module docstring); with :meth:`wrap_prompts`, also every
    prompt the LLM was sent, by step (``prompts[step]``: one per attempt)."""

    events: list[Event] = field(default_factory=list)
    step: int = 0
    prompts: dict[int, list[Prompt]] = field(default_factory=dict)

    def wrap(self, environment: Environment, perception: Perception) -> tuple[Environment, Perception]:
        """The components to run the trial with: the same ones, recording into this capture."""
        return _CapturingEnvironment(environment, self), _CapturingPerception(perception, self)

    def wrap_prompts(self, builder: PromptBuilder) -> PromptBuilder:
        """``builder``, recording each prompt it builds under the current step."""
        return _CapturingPromptBuilder(builder, self)

    def observed(self, observation: Observation, world: WorldSnapshot | None) -> None:
        self.events.append(Observed(world, observation.pose, float(observation.sim_time_s)))

    def seen(self, observation: Observation, modalities: Modalities) -> None:
        self.step += 1
        self.events.append(Seen(self.step, observation.lidar, dict(modalities.images), dict(modalities.texts)))


def _snapshot(environment: Environment) -> WorldSnapshot | None:
    take = getattr(environment, "snapshot", None)
    return take() if callable(take) else None


class _CapturingEnvironment(Environment):
    """The trial's environment, recording each observation and command (everything else passes through)."""

    def __init__(self, inner: Environment, capture: TrialCapture) -> None:
        self._inner, self._capture = inner, capture

    def __getattr__(self, name: str) -> Any:  # robot, options, ... of the wrapped environment
        return getattr(self._inner, name)

    @property
    def robot(self) -> RobotSpec:  # type: ignore[override]  # read-only here: the wrapped environment's robot
        return self._inner.robot

    def reset(self, seed: int) -> Observation:
        observation = self._inner.reset(seed)
        self._capture.observed(observation, _snapshot(self._inner))
        return observation

    def observe(self) -> Observation:
        observation = self._inner.observe()
        self._capture.observed(observation, _snapshot(self._inner))
        return observation

    def sense(self) -> Observation | None:
        reading = self._inner.sense()
        if isinstance(reading, Observation):  # the world when an answer arrived (an arm's fresh_scan)
            self._capture.observed(reading, _snapshot(self._inner))
        return reading

    def another_call(self) -> None:
        self._inner.another_call()

    def drive(self, linear_mm_s: float, angular_deg_s: float, seconds: float) -> ExecutionResult | None:
        return self._inner.drive(linear_mm_s, angular_deg_s, seconds)

    def execute(self, signal: ControlSignal) -> ExecutionResult:
        before = _snapshot(self._inner)
        result = self._inner.execute(signal)
        self._capture.events.append(Executed(self._capture.step, signal, result, before, _snapshot(self._inner),
                                             self._inner.pose()))
        return result

    def outcome(self):
        return self._inner.outcome()

    def pose(self) -> Pose | None:
        return self._inner.pose()

    def trajectory_png(self, poses, outcome):
        return self._inner.trajectory_png(poses, outcome)

    def snapshot(self) -> WorldSnapshot | None:
        return _snapshot(self._inner)

    def close(self) -> None:
        self._inner.close()


class _CapturingPerception(Perception):
    """The trial's perception, recording what each step's decision reads."""

    def __init__(self, inner: Perception, capture: TrialCapture) -> None:
        self._inner, self._capture = inner, capture

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def perceive(self, observation: Observation) -> Modalities:
        modalities = self._inner.perceive(observation)
        self._capture.seen(observation, modalities)
        return modalities


class _CapturingPromptBuilder(PromptBuilder):
    """The trial's prompt builder, recording what each attempt was sent."""

    def __init__(self, inner: PromptBuilder, capture: TrialCapture) -> None:
        self._inner, self._capture = inner, capture

    def __getattr__(self, name: str) -> Any:
        return getattr(self._inner, name)

    def build(self, request: Any) -> Prompt:
        prompt = self._inner.build(request)
        self._capture.prompts.setdefault(self._capture.step, []).append(prompt)
        return prompt

    def security_prefix_variants(self) -> list[str] | None:
        return self._inner.security_prefix_variants()

    def security_prefix(self, variant: str) -> str | None:
        return self._inner.security_prefix(variant)
