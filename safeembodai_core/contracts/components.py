"""The interfaces a plugin's components implement.

A plugin registers a *factory* for each named component (see :mod:`safeembodai_core.hookspecs`);
the factory receives the component's validated options and a :class:`BuildContext` and returns
an object with the methods below. Subclassing these ABCs is optional but recommended: a
missing method then fails at construction with a clear message instead of mid-trial.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections import Counter
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from ..models import (
    AttackRecord, BackendReply, ControlLimits, ControlSignal, ExecutionResult, Modalities, Observation, Outcome, Pose,
    Prompt, PromptRequest, ReferenceState, StepRecord, TrialResult, TrialSpec,
)
from .descriptions import BackendDescription, BackendOptions  # noqa: F401  (re-exported)
from .robot import RobotSpec
from ..validation.context import Validator

__all__ = ["Attacker", "AttackSurface", "BackendReply", "BuildContext", "Environment", "LLMBackend", "Perception",
           "PromptBuilder", "RobotSpec", "SceneObject", "StateStore", "StepFacts", "Validator", "WorldSnapshot"]


@dataclass(frozen=True)
class BuildContext:
    """Passed to every component factory: who is building and with which seed material.

    ``component`` is the registered name, ``kind`` the component kind, ``seed`` the trial's seed
    for per-trial components (0 for environments, which get it in ``reset``, state stores and
    ``Guard``'s rules), ``label`` the key of this use (the scenario's ``label:``, else the
    registered name; None only when built without a context), ``run_dir`` the run folder (None
    outside ``safeembodai run`` / ``ablate``), ``only_to_describe`` True when the component is built
    only to describe itself or quote a price (``ablate --dry-run``, ``--max-cost``): it will make no
    call, so a backend needs no key then. See ``docs/plugin_hooks.md``.
    """

    component: str
    kind: str
    seed: int = 0
    label: str | None = None  # the key of this use of the component: its label, else the name
    run_dir: str | None = None
    only_to_describe: bool = False


@dataclass(frozen=True)
class SceneObject:
    """One thing in a simulated world, as a disc on the floor (world frame, millimetres): ``kind`` is
    ``can``, ``ball``, ``labbot``, ``obstacle`` or a plugin's own word."""

    kind: str
    x_mm: float
    y_mm: float
    radius_mm: float
    heading_deg: float | None = None


@dataclass(frozen=True)
class WorldSnapshot:
    """What a simulator knows of its world at one instant: its clock, the room's extent (a square
    of ``room_mm`` from the origin, when it has one) and its objects. For pictures and exported
    bags only: ground truth, which no defence may read."""

    sim_time_s: float
    objects: tuple[SceneObject, ...] = ()
    room_mm: float | None = None


class Environment(ABC):
    """A (simulated) world with one robot; owns its physics and its sensors."""

    robot: RobotSpec = RobotSpec()

    @abstractmethod
    def reset(self, seed: int) -> Observation:
        """Build a fresh world from ``seed`` and return the first observation."""

    @abstractmethod
    def observe(self) -> Observation:
        """Read every sensor now."""

    @abstractmethod
    def execute(self, signal: ControlSignal) -> ExecutionResult:
        """Carry out one control signal; the world (moving obstacles too) advances meanwhile."""

    @abstractmethod
    def outcome(self) -> Outcome | None:
        """``COMPLETED``, ``INTERRUPTED`` or ``TIMEOUT`` (simulated time) once decided, else None."""

    def pose(self) -> Pose | None:
        """The robot's pose now, without reading the sensors (for trajectories); None if unknown."""
        return None

    def sense(self) -> Observation | None:
        """Optional: the LiDAR, pose and clock at the moment the LLM's answer arrives, for an arm
        with ``fresh_scan`` (its validators judge this reading, not the step's observation).

        The world first spends the time the LLM took (the think time, if it has not passed yet),
        then the LiDAR is read; no camera frame is needed. A collision during that time is
        reported in the returned ``truth`` exactly as :meth:`observe` reports one, once. Calling it
        again before anything moves reads the same world. None (the default): the environment
        cannot read its sensors between observations; an arm with ``fresh_scan`` is refused.
        """
        return None

    def another_call(self) -> None:
        """Optional: the LLM is asked again for the same observation (a refused answer's retry,
        Algorithm 1). An environment that charges the time each call takes owes another think time,
        spent as the first one is (before the next command, or in :meth:`sense`); the default charges
        nothing: the step's one think time covers every retry."""

    def drive(self, linear_mm_s: float, angular_deg_s: float, seconds: float) -> ExecutionResult | None:
        """Optional: hold a velocity for ``seconds`` of simulated time -- forward speed (mm/s, negative
        backwards) and turn rate (degrees/s, counter-clockwise), a differential drive's arc -- while the
        world moves with it; zero for both: the robot stands while the world moves. The result says how
        far and how much it turned (signed), and a contact as :meth:`execute` reports one; no think time
        is spent (the caller's clock is the time). None (the default): the environment cannot be driven
        by velocity, and ``safeembodai serve-robot`` refuses it."""
        return None

    def trajectory_png(self, poses: list[Pose], outcome: Outcome | None) -> bytes | None:
        """Optional: a top-down picture of the trial (room, obstacles, path, outcome)."""
        return None

    def snapshot(self) -> WorldSnapshot | None:
        """Optional: the world now (clock and objects) for exported bags, without reading the
        sensors or advancing anything; None when the environment cannot say."""
        return None

    def close(self) -> None:
        """Release the world's resources."""


#: The optional methods of :class:`Environment` and what the default (the class's own) does when an
#: environment does not implement one -- the one place that says it; :func:`as_environment` declares
#: each for an environment that is not a subclass, and wrappers (the capture, the staged worlds) must
#: pass every one on (their tests list :class:`Environment`'s public methods).
OPTIONAL_ENVIRONMENT_METHODS: dict[str, str] = {
    "pose": "None: the pose is unknown between observations (no trajectory)",
    "sense": "None: no reading between observations (an arm with fresh_scan is refused)",
    "another_call": "nothing: the step's one think time covers every retry",
    "drive": "None: the room cannot be driven by velocity (serve-robot refuses it)",
    "trajectory_png": "None: no picture of the trial",
    "snapshot": "None: no ground truth for bags and recordings",
    "close": "nothing to release",
}


class _DeclaredEnvironment(Environment):
    """An object with ``reset``, ``observe``, ``execute`` and ``outcome`` that does not subclass
    :class:`Environment`, with every optional method declared: the object's own where it has one,
    else the class's default (:func:`as_environment`)."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        self.robot = getattr(inner, "robot", Environment.robot)

    def _own(self, name: str) -> Any:
        method = getattr(self.inner, name, None)
        return method if callable(method) else None

    def reset(self, seed: int) -> Observation:
        return self.inner.reset(seed)

    def observe(self) -> Observation:
        return self.inner.observe()

    def execute(self, signal: ControlSignal) -> ExecutionResult:
        return self.inner.execute(signal)

    def outcome(self) -> Outcome | None:
        return self.inner.outcome()

    def pose(self) -> Pose | None:
        own = self._own("pose")
        return own() if own else None

    def sense(self) -> Observation | None:
        own = self._own("sense")
        return own() if own else None

    def another_call(self) -> None:
        own = self._own("another_call")
        if own:
            own()

    def drive(self, linear_mm_s: float, angular_deg_s: float, seconds: float) -> ExecutionResult | None:
        own = self._own("drive")
        return own(linear_mm_s, angular_deg_s, seconds) if own else None

    def trajectory_png(self, poses: list[Pose], outcome: Outcome | None) -> bytes | None:
        own = self._own("trajectory_png")
        return own(poses, outcome) if own else None

    def snapshot(self) -> WorldSnapshot | None:
        own = self._own("snapshot")
        return own() if own else None

    def close(self) -> None:
        own = self._own("close")
        if own:
            own()


def as_environment(environment: Any) -> Environment:
    """``environment`` as an :class:`Environment`: itself when it is one; an object that only has the
    four required methods (a duck-typed plugin's, a test's) wrapped so that the core calls declared
    methods only. Raises ``TypeError`` naming what is missing."""
    if isinstance(environment, Environment):
        return environment
    missing = [name for name in ("reset", "observe", "execute", "outcome")
               if not callable(getattr(environment, name, None))]
    if missing:
        raise TypeError(f"an environment needs {', '.join(missing)}; got {type(environment).__name__}")
    return _DeclaredEnvironment(environment)


class Perception(ABC):
    """Turns raw sensor readings into the modalities a prompt carries."""

    @abstractmethod
    def perceive(self, observation: Observation) -> Modalities:
        """Render ``observation`` (camera image, LiDAR image, text descriptions)."""


class PromptBuilder(ABC):
    """Renders the system prompt Y = {B, p} and the user prompt I_i for one attempt."""

    @abstractmethod
    def build(self, request: PromptRequest) -> Prompt:
        """Render ``request`` into a :class:`Prompt`; untrusted text stays data."""

    def security_prefix_variants(self) -> list[str] | None:
        """Names accepted as ``security_prefix``; None if unknown (then scenarios are not checked)."""
        return None

    def security_prefix(self, variant: str) -> str | None:
        """The security prefix p of ``variant`` alone, as Y would carry it, for an agent whose prompt
        is not built here (guard-mcp's server instructions); None: this builder cannot say it apart
        from a prompt."""
        return None


@dataclass
class StepFacts:
    """What the stored steps of one trial add up to, for the report (:meth:`StateStore.step_facts`).

    ``refusals`` counts, per validator rule, the attempts it refused (judged invalid for at least
    one of their signals; an attempt refused by two rules counts for each); ``attacked_by_kind``
    counts, per attack kind, the steps with at least one :class:`~safeembodai_core.models.AttackRecord`
    of that kind.
    """

    refusals: Counter = field(default_factory=Counter)  # rule -> attempts it refused
    attacked_by_kind: Counter = field(default_factory=Counter)  # kind -> steps attacked with it

    def add(self, record: StepRecord) -> None:
        """Count one step record in."""
        refused = {(a.index, v.rule) for a in record.attempts for v in a.verdicts if not v.valid}
        self.refusals.update(rule for _, rule in refused)
        self.attacked_by_kind.update({a.kind for a in record.attacks})


class StateStore(ABC):
    """Keeps per-step records and answers the reference state R_{i-1}.

    The store records every step whatever the arm; the *state management* defence only decides
    whether R_{i-1} goes into the prompt.
    """

    @abstractmethod
    def begin_trial(self, spec: TrialSpec) -> None:
        """Start recording ``spec`` (any earlier, unfinished record of the same trial is dropped)."""

    @abstractmethod
    def record_step(self, record: StepRecord) -> None:
        """Persist one step atomically, replacing any earlier record of the same (trial, step).

        The loop writes a step with an accepted plan twice: before execution (``status``
        ``"executing"``, ``planned`` set) and after (``"done"``); see ``docs/plugin_hooks.md``.
        """

    @abstractmethod
    def reference_state(self, trial_id: str, step: int) -> ReferenceState | None:
        """R_{step-1} for the prompt of ``step``; None on the first step."""

    @abstractmethod
    def end_trial(self, result: TrialResult) -> None:
        """Persist the trial's result."""

    @abstractmethod
    def steps(self, trial_id: str) -> list[StepRecord]:
        """Every recorded step of a trial, in order."""

    def step_facts(self, trial_ids: Iterable[str]) -> dict[str, StepFacts]:
        """Refusals per rule and attacked steps per kind of each of ``trial_ids`` (what the report
        counts; a trial without steps has empty counts).

        The default counts the records :meth:`steps` returns. A store that can count without
        reading every record back (the ``sqlite`` store asks its tables) may override it; the
        numbers must be the same.
        """
        facts: dict[str, StepFacts] = {}
        for trial_id in trial_ids:
            facts[trial_id] = counted = StepFacts()
            for record in self.steps(trial_id):
                counted.add(record)
        return facts

    def results(self) -> list[TrialResult]:
        """Every finished trial's result (what resuming and reports read).

        Stores that do not keep results across processes may leave this unimplemented; an
        ablation then cannot be resumed from them.
        """
        raise NotImplementedError(f"{type(self).__name__} does not keep trial results")

    @property
    def persistent(self) -> bool:
        """True when records survive the process (a resumed ablation can read them)."""
        return False

    @property
    def thread_safe(self) -> bool:
        """True when several threads may call the store at once (``ablate --concurrency`` then
        shares it without a lock around each call: work done before the store's own lock, such as
        serialising a record, overlaps other threads' calls). False by default: calls are serialised."""
        return False

    def close(self) -> None:
        """Flush and release."""


class Attacker(ABC):
    """An adversary that may tamper with a step's inputs before the LLM sees them."""

    @abstractmethod
    def attack(self, target: "AttackSurface") -> list[AttackRecord]:
        """Alter ``target`` in place (instruction, observation, reference state) and return
        one ground-truth record per alteration (empty when this step is left alone)."""


class LLMBackend(ABC):
    """Answers a prompt with raw text; the core parses and validates it.

    ``concurrency`` is how many trials ``ablate`` keeps in flight per worker by default (when not
    given ``--concurrency``): 1 for a backend that computes, more for one that waits on a remote model.
    """

    concurrency: int = 1

    @abstractmethod
    def complete(self, prompt: Prompt, rng: np.random.Generator) -> "BackendReply":
        """Send ``prompt``; raise :class:`~safeembodai_core.errors.BackendError` when no answer can be had."""

    def prepare_attempt(self, index: int, limits: ControlLimits, rng: np.random.Generator) -> dict[str, Any] | None:
        """Optional: called by Algorithm 1 before attempt ``index`` of a step (0 is the first try),
        with the step's actuation ``limits`` and the attempt's seeded ``rng`` (the one
        :meth:`complete` then receives). A backend that decodes under the limits, or makes a retry
        differ from the refused answer (a temperature step, a per-attempt seed), prepares it here
        and returns what it will send; the dict is recorded as ``Attempt.sampling``. The default
        prepares nothing and returns None."""
        return None

    def cache_request(self, prompt: Prompt) -> dict[str, Any] | None:
        """Optional: what :meth:`complete` would send for ``prompt`` after the last
        :meth:`prepare_attempt` (model, messages, images, sampling, seed; never a key), as JSON
        values, without sending it or consuming the prepared attempt. A backend that returns it
        has its replies kept in the run's response cache (``docs/ablations.md``) and replayed for
        the same request at the same point of the same trial, so a resumed or repeated run pays
        no call twice. The default, None, keeps nothing: a simulated pilot costs nothing."""
        return None

    def cost(self, prompt_tokens: int, completion_tokens: int) -> float | None:
        """Optional: what that many tokens cost in US dollars at the provider's list price, for
        ``ablate --max-cost``; None (the default) when no price is known."""
        return None

    def preflight(self) -> None:
        """Optional: raise :class:`~safeembodai_core.errors.BackendError` (one line) when this backend
        cannot work at all -- a server that does not answer, say. ``safeembodai run`` and ``ablate``
        call it once before the first trial (before any run folder exists); it must be cheap and
        never spend tokens. The default checks nothing."""

    def close(self) -> None:
        """Release connections."""


class _DeclaredBackend(LLMBackend):
    """An object with a ``complete`` that does not subclass :class:`LLMBackend`, with every optional
    method declared: the object's own where it has one, else the class's default (:func:`as_llm_backend`)."""

    def __init__(self, inner: Any) -> None:
        self.inner = inner
        concurrency = getattr(inner, "concurrency", 1)
        self.concurrency = concurrency if isinstance(concurrency, int) and not isinstance(concurrency, bool) else 1

    def _own(self, name: str) -> Any:
        method = getattr(self.inner, name, None)
        return method if callable(method) else None

    def complete(self, prompt: Prompt, rng: np.random.Generator) -> "BackendReply":
        return self.inner.complete(prompt, rng)

    def prepare_attempt(self, index: int, limits: ControlLimits, rng: np.random.Generator) -> dict[str, Any] | None:
        own = self._own("prepare_attempt")
        return own(index=index, limits=limits, rng=rng) if own else None

    def cache_request(self, prompt: Prompt) -> dict[str, Any] | None:
        own = self._own("cache_request")
        return own(prompt) if own else None

    def cost(self, prompt_tokens: int, completion_tokens: int) -> float | None:
        own = self._own("cost")
        return own(prompt_tokens, completion_tokens) if own else None

    def preflight(self) -> None:
        own = self._own("preflight")
        if own:
            own()

    def close(self) -> None:
        own = self._own("close")
        if own:
            own()


def as_llm_backend(backend: Any) -> LLMBackend:
    """``backend`` as an :class:`LLMBackend`: itself when it is one; an object that only has a
    ``complete`` (a duck-typed plugin's, a test's) wrapped so that the core calls declared methods
    only. Raises ``TypeError`` for an object without a callable ``complete``."""
    if isinstance(backend, LLMBackend):
        return backend
    if not callable(getattr(backend, "complete", None)):
        raise TypeError(f"an LLM backend needs a complete(prompt, rng) method; got {type(backend).__name__}")
    return _DeclaredBackend(backend)


@dataclass
class AttackSurface:
    """The inputs of one step as an attacker sees them; attackers mutate it in place.

    ``instruction`` is the human instruction h_i, ``observation`` the raw sensor readings (a
    spoofed LiDAR also fools the validators, as a real one would), ``reference_state`` R_{i-1}
    (None when state management is off or on the first step). ``rng`` is seeded from the
    trial seed, the attacker's key and the step index only, so every arm of an ablation sees
    the same attacks at the same steps (:class:`~safeembodai_core.contracts.attack_schedule.AttackSchedule` decides
    when). ``step`` counts from 1; ``limits`` are the scenario's actuation limits. The
    ``observation`` is a shallow copy: reassign its fields, never write into its arrays; the
    validators' pose comes from the real observation, not from this copy.
    """

    step: int
    instruction: str
    observation: Observation
    reference_state: ReferenceState | None
    rng: np.random.Generator
    limits: ControlLimits = ControlLimits()
