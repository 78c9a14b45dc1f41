"""One trial: the step loop around Algorithm 1, from world reset to outcome.

Per step i: read the sensors -> attackers may alter the instruction, the readings or the
reference state -> perception renders the modalities -> the prompt carries the security prefix
and R_{i-1} when those defences are on -> Algorithm 1 -> record the accepted plan (write-ahead)
-> execute it (stopping at the first collision or stop) -> record R_i -> ask the world for an
outcome.

Write-ahead: a step with an accepted plan is stored before the environment moves (``status``
``executing``, ``planned`` set) and again after (``status`` ``done``), through the same
``record_step`` (stores replace a step recorded again). A plan that cannot be stored is not
executed; a result that cannot be stored leaves the plan on record. Either way the trial ends
``error`` with a one-line detail. Every record is a :func:`~safeembodai_core.trust.text.storable`
copy: what an answer holds cannot make storing fail.
"""

from __future__ import annotations

import copy
import time
from functools import partial
from dataclasses import dataclass, field
from typing import Any, Callable, Literal


from ..contracts.attack_schedule import attack_stream, run_attackers
from ..contracts.components import (
    Attacker, AttackSurface, Environment, LLMBackend, as_llm_backend, Perception, PromptBuilder, StateStore, Validator,
)
from ..errors import BackendError, SafeEmbodAIError, StateStoreError
from ..logs import get_logger
from ..models import (
    DEFAULT_LIMITS,
    ControlLimits,
    ExecutedSignal,
    Observation,
    Outcome,
    PromptRequest,
    StepRecord,
    Straight,
    TrialResult,
    TokenUsage,
    TrialSpec,
)
from ..models.prompt import DEFAULT_INSTRUCTION, DEFAULT_TASK
from ..models.records import ErrorKind
from ..trust.text import one_line, storable
from ..validation.context import PastScan, ValidationContext
from .defences import Defences
from .fresh_scan import fresh_context, require_sense
from .enforce import enforce
from .guarded_step import decide


log = get_logger(__name__)

@dataclass
class TrialParts:
    """The components one trial runs with (built from a scenario, or handed in by a library user)."""

    environment: Environment
    perception: Perception
    prompt_builder: PromptBuilder
    state: StateStore
    backend: LLMBackend
    validators: list[tuple[str, Validator]] = field(default_factory=list)
    attackers: list[tuple[str, Attacker]] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.backend = as_llm_backend(self.backend)  # its optional methods declared: the loop calls them


@dataclass(frozen=True)
class LoopSettings:
    """The trial's budget, the human instruction and task, the arm's defences and the limits.

    ``budget`` says what ``max_steps`` counts: ``steps`` (ours), or ``attempts`` -- LLM answers,
    retries included, as the authors' release counts them (eyesimLLM
    ``src/discrete_robot/discrete_llm_robot.py:110, 162``): no step starts once the attempts used
    reach ``max_steps``, and a step left without an acceptable answer ends the trial as
    ``timeout`` when they have (``:223``), else as ``safe_abort`` (``:226-228``).
    """

    max_steps: int = 20
    instruction: str = DEFAULT_INSTRUCTION
    task: str = DEFAULT_TASK
    defences: Defences = field(default_factory=Defences)
    limits: ControlLimits = DEFAULT_LIMITS
    budget: Literal["steps", "attempts"] = "steps"


class _Notifier:
    def __init__(self, plugins: Any) -> None:
        self.plugins = plugins

    def __call__(self, hook: str, **kwargs: Any) -> None:
        if self.plugins is not None:
            self.plugins.notify(hook, **kwargs)

    def safely(self, hook: str, **kwargs: Any) -> None:
        """For hooks called after the outcome is decided: a failing plugin is logged, not fatal."""
        try:
            self(hook, **kwargs)
        except SafeEmbodAIError as error:
            log.warning("hook.failed", hook=hook, error=str(error))


@dataclass
class _Totals:
    steps: int = 0
    prompt: int = 0
    completion: int = 0
    estimated: bool = False
    distance: float = 0.0
    collisions: int = 0
    collisions_self: int = 0
    collisions_struck: int = 0
    collisions_struck_standing: int = 0
    collision_note: str = ""  # the last collision, for an interrupted trial's detail
    self_hit: dict[str, int] = field(default_factory=dict)  # self collisions by what was hit
    interventions: int = 0
    retries: int = 0
    enforced_steps: int = 0
    attacked: int = 0
    flagged: int = 0
    caught: int = 0
    visible: int = 0
    first_seen: int | None = None
    lost: int = 0
    trajectory: list[Any] = field(default_factory=list)
    world: str = ""  # the first observation's truth.world_kind
    models: list[str] = field(default_factory=list)  # the model names the replies gave, first seen first

    def add(self, record: StepRecord) -> None:
        usage = record.usage
        self.steps += 1
        self.prompt += usage.prompt_tokens
        self.completion += usage.completion_tokens
        self.estimated = self.estimated or usage.estimated
        self.interventions += record.interventions
        self.retries += record.retries
        self.enforced_steps += record.enforced is not None and record.enforced.ran
        self.attacked += bool(record.attacks)
        self.flagged += record.flagged_attack
        for attempt in record.attempts:
            if attempt.model and attempt.model not in self.models and len(self.models) < 8:
                self.models.append(attempt.model)
        self.caught += bool(record.attacks) and record.flagged_attack
        self.visible += record.truth.target_in_view
        if record.truth.target_in_view and self.first_seen is None:
            self.first_seen = record.step
        elif not record.truth.target_in_view and self.first_seen is not None:
            self.lost += 1
        self.observed(record.step, record.truth)
        for item in record.executed:
            if isinstance(item.signal, Straight):
                self.distance += abs(item.result.distance_mm)
            if item.result.collided:
                self._collided(record.step, item.result.collision, item.result.detail, item.result.hit)
                # a mover that struck in the think time before the command moved: the robot stood
                self.collisions_struck_standing += item.result.collision == "struck" and item.result.before_motion

    def spent(self, usage: Any) -> None:
        """Tokens paid outside any recorded step (a step whose backend gave up): counted all the same."""
        if isinstance(usage, TokenUsage):
            self.prompt += usage.prompt_tokens
            self.completion += usage.completion_tokens
            self.estimated = self.estimated or usage.estimated

    def observed(self, step: int, truth: Any) -> None:
        """Count a collision outside any command (a Labbot ran into the robot while it waited),
        which the environment reports once, in the next observation's truth."""
        if truth.collision is not None:
            self._collided(step, truth.collision, truth.collision_detail, truth.hit)
            self.collisions_struck_standing += truth.collision == "struck"  # outside any command

    def _collided(self, step: int, collision: str | None, detail: str, hit: str | None = None) -> None:
        self.collisions += 1
        self.collisions_self += collision == "self"
        self.collisions_struck += collision == "struck"
        if collision == "self":
            kind = one_line(hit)[:32] if hit else "unknown"
            self.self_hit[kind] = self.self_hit.get(kind, 0) + 1
        self.collision_note = f"{collision or 'unattributed'} collision at step {step}: {detail}"

    def result(self, spec: TrialSpec, outcome: Outcome, detail: str, wall_time_s: float,
               error_kind: ErrorKind | None = None) -> TrialResult:
        return TrialResult(
            spec=spec, outcome=outcome, steps=self.steps, prompt_tokens=self.prompt, completion_tokens=self.completion,
            tokens_estimated=self.estimated,
            distance_mm=self.distance, collisions=self.collisions, collisions_self=self.collisions_self,
            collisions_struck=self.collisions_struck, self_collisions_hit=dict(self.self_hit),
            collisions_struck_standing=self.collisions_struck_standing,
            interventions=self.interventions,
            retries=self.retries, enforced_steps=self.enforced_steps, attacked_steps=self.attacked,
            flagged_steps=self.flagged,
            flagged_attacked_steps=self.caught, target_visible_steps=self.visible, first_seen_step=self.first_seen,
            lost_after_seen_steps=self.lost, detail=one_line(detail), trajectory=self.trajectory,
            wall_time_s=wall_time_s, error_kind=error_kind if outcome == Outcome.ERROR else None, world=self.world,
            models=list(self.models),
        )


def _cost(backend: LLMBackend, result: TrialResult) -> float | None:
    """What the trial's tokens cost at the backend's list price; None when it knows none (or its
    ``cost`` fails: a price is a report's convenience, never a reason to lose a trial)."""
    try:
        cost = backend.cost(result.prompt_tokens, result.completion_tokens)
    except Exception as error:
        log.warning("trial.unpriced", trial=result.spec.trial_id, error=one_line(f"{type(error).__name__}: {error}"))
        return None
    if cost is None or isinstance(cost, bool) or not isinstance(cost, (int, float)) or not 0 <= cost <= 1e9:
        return None  # nan, negative, absurd or not a number: no price rather than a wrong one
    return float(cost)


def error_result(spec: TrialSpec, detail: str) -> TrialResult:
    """The result of a trial that could not even start (its components failed to build)."""
    return storable(_Totals().result(spec, Outcome.ERROR, detail, 0.0, "build"))


def run_trial(spec: TrialSpec, parts: TrialParts, settings: LoopSettings, plugins: Any = None) -> TrialResult:
    """Run one trial to its outcome and return its result (also stored in ``parts.state``).

    A backend that fails after its own retries, a plugin that raises or a store that cannot
    write ends the trial with outcome ``error`` and a one-line detail; everything recorded
    before stays recorded, and every command the environment executed is on record (as
    planned, or executed). Nothing but a ``BaseException`` escapes.
    """
    notify = _Notifier(plugins)
    started = time.perf_counter()
    totals = _Totals()
    outcome: Outcome | None = None
    detail, step = "", 0
    error_kind: ErrorKind = "crash"
    try:
        notify("before_trial", spec=spec)
        _store(lambda: parts.state.begin_trial(spec), "begin the trial")
        if settings.defences.fresh_scan and settings.defences.safety_validation:
            require_sense(parts.environment)  # before any answer is paid for
        observation = parts.environment.reset(spec.seed)
        totals.world = one_line(observation.truth.world_kind or "")[:64]
        if observation.pose is not None:
            totals.trajectory.append(observation.pose)
        history: list[PastScan] = []  # the validators' earlier scans (ValidationContext.history)
        attempts = 0  # LLM answers so far, for budget: attempts
        by_attempts = settings.budget == "attempts"
        for step in range(1, settings.max_steps + 1):
            if by_attempts and attempts >= settings.max_steps:
                outcome, detail = Outcome.TIMEOUT, f"attempt budget of {settings.max_steps} spent"
                break
            if step > 1:
                observation = parts.environment.observe()
                ended = parts.environment.outcome()
                if ended is not None:  # the world ended while the robot waited: no LLM call for nothing
                    totals.observed(step - 1, observation.truth)
                    outcome = ended
                    break
            notify("before_step", spec=spec, step=step, observation=observation)

            def sensed(reading: Observation, step: int = step) -> None:
                totals.observed(step, reading.truth)

            record = storable(_decide(spec, step, observation, parts, settings, history, sensed))
            if record.planned:
                _store(lambda: parts.state.record_step(record),
                       f"record the plan of step {step} before executing it (nothing of it ran)")
            record = storable(_execute(record, parts, totals.trajectory))
            totals.add(record)
            _store(lambda: parts.state.record_step(record),
                   f"record the results of step {step} (its plan is on record as executing)")
            notify("after_step", spec=spec, record=record)
            attempts += len(record.attempts)
            outcome = parts.environment.outcome() if not record.accepted else None
            if outcome is not None:  # the world ended while the LLM thought (fresh_scan found it): not an abort
                break
            if not record.accepted and settings.defences.on_exhausted == "abort":
                outcome = Outcome.SAFE_ABORT
                detail = f"no acceptable answer after {len(record.attempts)} attempts at step {step}"
                if by_attempts and attempts >= settings.max_steps:  # the release's counter decides (:223)
                    outcome = Outcome.TIMEOUT
                    detail += f"; attempt budget of {settings.max_steps} spent"
                break
            outcome = parts.environment.outcome()
            if outcome is not None:
                break
        else:
            outcome, detail = Outcome.TIMEOUT, f"step budget of {settings.max_steps} spent"
    except SafeEmbodAIError as error:  # backend outage, plugin failure, unreadable store
        outcome, detail = Outcome.ERROR, str(error)
        if isinstance(error, BackendError):
            totals.spent(error.spent)  # paid before the backend gave up: on the trial's count
        error_kind = ("backend" if isinstance(error, BackendError) else
                      "store" if isinstance(error, StateStoreError) else "reported")
        log.warning("trial.error", trial=spec.trial_id, step=step, error=detail)
        notify.safely("on_step_error", spec=spec, step=step, error=error)
    except Exception as error:  # a component bug must not take the whole ablation down
        outcome, detail = Outcome.ERROR, f"{type(error).__name__}: {error}"
        log.exception("trial.crashed", trial=spec.trial_id, step=step)
        notify.safely("on_step_error", spec=spec, step=step, error=error)
    if outcome == Outcome.TIMEOUT and not detail:
        detail = "simulated time limit reached"
    if outcome == Outcome.INTERRUPTED and not detail:
        detail = totals.collision_note
    result = storable(totals.result(spec, outcome or Outcome.ERROR, detail, time.perf_counter() - started, error_kind))
    result.cost_usd = _cost(parts.backend, result)
    try:
        _store(lambda: parts.state.end_trial(result), "record the trial's result")
    except StateStoreError as error:  # the trial is not on record as finished: resuming re-runs it
        log.warning("trial.unrecorded", trial=spec.trial_id, error=str(error))
        was = f"{result.outcome.value}: {result.detail}" if result.detail else result.outcome.value
        result = storable(totals.result(spec, Outcome.ERROR, f"{error} (the trial had ended {was})",
                                        time.perf_counter() - started, "store"))
        try:
            parts.state.end_trial(result)
        except Exception as again:  # the caller still gets the result; the store is beyond help
            log.warning("trial.unrecorded", trial=spec.trial_id, error=one_line(f"{type(again).__name__}: {again}"))
    notify.safely("after_trial", spec=spec, result=result)
    return result


def _store(call: Any, what: str) -> Any:
    """Run one store call (a write, or a read); return what it returns. Any failure becomes a one-line
    :class:`StateStoreError` saying what was lost or could not be read."""
    try:
        return call()
    except StateStoreError as error:
        raise StateStoreError(one_line(f"state store could not {what}: {error}")) from error
    except Exception as error:  # a third-party store's bug is a store failure, not a crash of the ablation
        raise StateStoreError(one_line(f"state store could not {what}: {type(error).__name__}: {error}")) from error


def _decide(spec: TrialSpec, step: int, observation: Observation, parts: TrialParts,
            settings: LoopSettings, history: list[PastScan] | None = None,
            on_sensed: Callable[[Observation], None] | None = None) -> StepRecord:
    """Step i up to execution: attackers, perception, Algorithm 1; the record with the accepted plan.
    ``on_sensed`` receives each reading the arm's ``fresh_scan`` takes as an answer arrives."""
    defences = settings.defences
    reference = (_store(lambda: parts.state.reference_state(spec.trial_id, step),
                        f"read the reference state of step {step}") if defences.state_management else None)
    # attackers get their own copy: reassigning observation.truth or .pose cannot corrupt ground truth
    surface = AttackSurface(step, settings.instruction, copy.copy(observation), reference,
                            rng=attack_stream(spec.seed, "", step), limits=settings.limits)
    attacks = run_attackers(surface, parts.attackers, spec.seed, step)
    request = PromptRequest(
        instruction=surface.instruction, modalities=parts.perception.perceive(surface.observation), step=step,
        security_prefix=defences.prefix_variant, reference_state=surface.reference_state,
        limits=settings.limits, task=settings.task,
        reference_view="last_command" if defences.state_management == "last_command" else "full",
    )
    # the scan as attacked (a spoofed sensor fools the rules too); the pose as the world reports it
    context = ValidationContext(scan=surface.observation.lidar, robot=parts.environment.robot, limits=settings.limits,
                                start_pose=observation.pose, sim_time_s=observation.sim_time_s,
                                history=tuple(history or ()))
    if history is not None and context.scan is not None and observation.pose is not None:
        history.append(PastScan(context.scan, observation.pose, observation.sim_time_s))
    fresh = None
    if defences.fresh_scan and defences.safety_validation:
        fresh = partial(fresh_context, context, observation, parts=parts, seed=spec.seed, step=step,
                        instruction=settings.instruction, reference=reference, limits=settings.limits,
                        on_sensed=on_sensed or (lambda reading: None))
    validators = parts.validators if defences.safety_validation else []
    judged: dict[int, ValidationContext] = {}
    attempts, response = decide(
        request, builder=parts.prompt_builder, backend=parts.backend,
        validators=validators,
        context=context, failure_threshold=defences.failure_threshold, seed=spec.seed, fresh=fresh,
        ended=(lambda: parts.environment.outcome() is not None) if fresh else None, judged=judged,
        retrying=getattr(parts.environment, "another_call", lambda: None),  # a duck-typed world charges nothing
    )
    planned = list(response.control) if response is not None else []
    enforced = None
    # on_exhausted: enforce -- the rules' cut of the last refused answer, judged again (never when the world
    # ended while the LLM thought: nothing runs then)
    if response is None and defences.on_exhausted == "enforce" and not (
            fresh is not None and parts.environment.outcome() is not None):
        enforced = enforce(attempts, judged, validators)
        planned = list(enforced.plan) if enforced.ran else []
    return StepRecord(
        trial_id=spec.trial_id, step=step, instruction=surface.instruction, attacks=attacks, attempts=attempts,
        planned=planned, accepted=response is not None, pose_before=observation.pose,
        truth=observation.truth, sim_time_s=observation.sim_time_s, status="executing" if planned else "done",
        enforced=enforced,
    )


def _execute(record: StepRecord, parts: TrialParts, trajectory: list[Any]) -> StepRecord:
    """Execute the record's plan (stopping at the first collision or stop); the record with R_i."""
    executed: list[ExecutedSignal] = []
    for signal in record.planned:
        result = parts.environment.execute(signal)
        executed.append(ExecutedSignal(signal=signal, result=result))
        pose = parts.environment.pose()
        if pose is not None:
            trajectory.append(pose)
        if result.collided or result.stopped:
            break
    return record.model_copy(update={"executed": executed, "pose_after": parts.environment.pose(), "status": "done"})
