"""Records of what happened: per attempt, per step (R_i) and per trial.

These are pydantic models so state stores can serialise them to JSON and read them back
unchanged. Nothing in them may carry a secret: backends report usage, never credentials, and
the trial loop hands stores only :func:`~safeembodai_core.trust.text.storable` copies (text
redacted and encodable). Numbers a backend reports are kept storable here: token counts are
clamped to SQLite's INTEGER, a NaN or infinite latency becomes 0.
"""

from __future__ import annotations

from enum import Enum
from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..trust.text import finite_or_zero, storable_int
from .control import ControlSignal
from .observation import Collision, GroundTruth, Pose
from .response import LLMResponse


class _Record(BaseModel):
    model_config = ConfigDict(extra="forbid")


class TokenUsage(_Record):
    """Tokens a call used. ``estimated``: the server's own count was missing or unusable, so these
    were counted here (the model's tokenizer over the request and the answer), never taken as 0."""

    prompt_tokens: int = Field(0, ge=0)
    completion_tokens: int = Field(0, ge=0)
    estimated: bool = False

    @field_validator("prompt_tokens", "completion_tokens")
    @classmethod
    def _clamped(cls, value: int) -> int:
        return storable_int(value)

    @property
    def total(self) -> int:
        return self.prompt_tokens + self.completion_tokens

    def __add__(self, other: "TokenUsage") -> "TokenUsage":
        return TokenUsage(
            prompt_tokens=self.prompt_tokens + other.prompt_tokens,
            completion_tokens=self.completion_tokens + other.completion_tokens,
            estimated=self.estimated or other.estimated,
        )




class ExecutionResult(_Record):
    """e_ij: what executing one control signal actually did.

    ``collision`` says who moved into whom when ``collided`` (None where the environment does not
    say); ``hit`` names what the robot touched -- ``wall``, ``ball``, ``labbot``, ``obstacle`` or
    ``can`` (touching the can is no collision) -- when the environment knows; ``before_motion``: the
    contact came before this command moved the robot (a mover struck it in the think time before the
    command ran): the robot stood, as far as a plan rule is concerned.
    """

    distance_mm: float = 0.0
    angle_deg: float = 0.0
    stopped: bool = False
    collided: bool = False
    collision: Collision | None = None
    hit: str | None = None
    before_motion: bool = False  # the contact came before the command moved the robot (in the think time)
    detail: str = ""

    @model_validator(mode="after")
    def _attributed_only_if_collided(self) -> "ExecutionResult":
        if self.collision is not None and not self.collided:
            raise ValueError(f"collision={self.collision!r} needs collided=True")
        return self


class ExecutedSignal(_Record):
    """(g_ij, e_ij): a control signal with its execution result."""

    signal: ControlSignal
    result: ExecutionResult


class Advice(_Record):
    """What a refusal offers instead, as numbers: the reason says the same in words for an LLM;
    a simulated pilot (the mock) reads these fields, never the words (a reworded reason changes
    nothing it does). Every field is optional: a rule says what it knows.

    ``safe_mm``: the most of the refused straight that is safe, as the reason states it (0: none
    now); ``safe_deg``: the most of the refused turn that is safe; ``wait``: nothing that way is
    safe now, wait for a moving obstacle to pass; ``step_aside``: a plan that leaves a moving
    obstacle's course, offered instead of the refused one.
    """

    safe_mm: float | None = Field(None, ge=0)
    safe_deg: float | None = Field(None, ge=0)
    wait: bool = False
    step_aside: list[ControlSignal] = Field(default_factory=list)
    #: how many characters of the verdict's reason it takes to say this advice in words (None: the
    #: reason does not say it): a prompt that cuts the reason shorter has cut the advice too
    words_end: int | None = Field(None, ge=0)


class Verdict(_Record):
    """One validator rule's judgement of one control signal; a refusal may carry :class:`Advice`."""

    rule: str
    valid: bool
    reason: str = ""
    signal_index: int | None = None
    advice: Advice | None = None

    def line(self) -> str:
        """The one way a refusal is written, wherever it is shown: ``rule (signal K): reason``, K from 1.

        Algorithm 1's feedback, :attr:`GuardReport.reasons`, the Gymnasium refusals and the Inspect
        transcript all use it (the reason is shown as written; each place makes it safe for its reader).
        """
        where = "" if self.signal_index is None else f" (signal {self.signal_index + 1})"
        return f"{self.rule}{where}: {self.reason}"


class Attempt(_Record):
    """One call to the LLM within a step (the first try or a retry of Algorithm 1)."""

    index: int
    raw_text: str = ""
    response: LLMResponse | None = None
    parse_error: str | None = None
    finish_reason: str | None = None  # the backend's reason the answer ended, as sent; None when not reported
    reasoning: str = ""  # reasoning the reply held apart from its answer (a provider's field, <think> blocks)
    choices: int | None = None  # how many choices the reply held; None when the backend handed over one text
    origin: str | None = None  # where the answer came from (scheme://host:port), when the backend knows
    model: str | None = None  # the model the reply says answered (the provider's own name), when it says
    verdicts: list[Verdict] = Field(default_factory=list)
    usage: TokenUsage = Field(default_factory=TokenUsage)
    latency_s: float = 0.0
    sampling: dict[str, int | float] | None = None  # what the backend sent to vary this attempt (temperature, seed)

    @field_validator("latency_s")
    @classmethod
    def _measured(cls, value: float) -> float:
        return max(0.0, finite_or_zero(value))

    @property
    def accepted(self) -> bool:
        return self.response is not None and all(v.valid for v in self.verdicts)

    def failures(self) -> list[str]:
        """Human-readable reasons this attempt was refused (fed back to the LLM on retry)."""
        if self.parse_error is not None:
            return [self.parse_error]
        # which signal of the plan a verdict is about (1-based), so the LLM can amend that one
        return [v.line() for v in self.verdicts if not v.valid]

    def refusals(self) -> list["Refusal"]:
        """:meth:`failures` as data, one :class:`Refusal` per reason, in the same order."""
        if self.parse_error is not None:
            return [Refusal(attempt=self.index + 1)]
        plan = list(self.response.control) if self.response is not None else []
        return [Refusal(attempt=self.index + 1, plan=plan, rule=v.rule, signal_index=v.signal_index, advice=v.advice)
                for v in self.verdicts if not v.valid]


class Refusal(_Record):
    """One line of a retry prompt's failures section, as data (Algorithm 1's feedback): the
    attempt it refused (from 1; None when the line names none, as a Gymnasium agent's reasons),
    the plan that attempt sent (empty: it did not parse), the rule and the signal (from 0) that
    refused it, and the rule's :class:`Advice`. The prompt shows the line; a simulated pilot reads this."""

    attempt: int | None = Field(None, ge=1)
    plan: list[ControlSignal] = Field(default_factory=list)
    rule: str | None = None
    signal_index: int | None = None
    advice: Advice | None = None
    #: how many characters of the failure line it takes to say the advice (from ``Advice.words_end``):
    #: a prompt builder that cuts the line shorter hands the refusal on without its advice
    advice_end: int | None = Field(None, ge=0)


class Enforced(_Record):
    """``on_exhausted: enforce`` (ours, not the paper's): what the loop made of a step whose N retries
    were spent -- the rules' own cut of the LLM's last parsed, refused answer, judged again.

    ``attempt``: the :attr:`Attempt.index` of the answer cut (None: no answer of the step parsed,
    nothing to cut); ``source``: ``cut`` (the signals before the first refused one, that one shortened
    to the least ``safe_mm``/``safe_deg`` its refusals allow, the rest dropped), ``step_aside`` (a
    refusal's whole alternative plan) or ``none``; ``plan``: that plan as built; ``verdicts``: every
    rule's verdict on it, on the context the cut answer was judged on; ``ran``: the plan passed and
    was handed to the environment (``StepRecord.planned``); otherwise the step held, without
    motion. ``note``: the same in one line. The LLM never wrote ``plan``: the rules cut it from its answer.
    """

    attempt: int | None = None
    source: Literal["cut", "step_aside", "none"] = "none"
    plan: list[ControlSignal] = Field(default_factory=list)
    verdicts: list[Verdict] = Field(default_factory=list)
    ran: bool = False
    note: str = ""

    @model_validator(mode="after")
    def _ran_only_if_valid(self) -> "Enforced":
        if self.ran and (not self.plan or not all(v.valid for v in self.verdicts)):
            raise ValueError("an enforced plan runs only when it is not empty and every rule passed it")
        return self


class AttackRecord(_Record):
    """Ground truth of an attack on a step: who, through which channel, with what payload."""

    attacker: str
    channel: Literal["instruction", "sensor", "state"]
    kind: str
    payload: str = ""


class ReferenceState(_Record):
    """R_{i-1}: the previous step's signals with their results, and what the LLM said then."""

    step: int
    executed: list[ExecutedSignal] = Field(default_factory=list)
    perception: list[dict[str, object]] = Field(default_factory=list)
    planning: str = ""
    outcome_note: str = ""


class StepRecord(_Record):
    """Everything about one step i of a trial; ``executed`` is R_i.

    The loop stores each step with an accepted plan twice: *before* execution with ``planned``
    set, ``executed`` empty and ``status`` ``"executing"`` (write-ahead), then with the results
    and ``status`` ``"done"``. A stored ``"executing"`` record is a step whose plan was handed to
    the environment but whose results were never recorded (the trial failed in between): any of
    ``planned`` may have run.
    """

    trial_id: str
    step: int
    instruction: str
    attacks: list[AttackRecord] = Field(default_factory=list)
    attempts: list[Attempt] = Field(default_factory=list)
    planned: list[ControlSignal] = Field(default_factory=list)  # the accepted plan, handed to the environment
    executed: list[ExecutedSignal] = Field(default_factory=list)
    status: Literal["executing", "done"] = "done"
    accepted: bool = False
    pose_before: Pose | None = None
    pose_after: Pose | None = None
    truth: GroundTruth = Field(default_factory=GroundTruth)
    sim_time_s: float = 0.0
    #: ``on_exhausted: enforce``: the rules' cut of the last refused answer (``accepted`` stays False: no
    #: answer of the LLM passed; ``planned`` holds the cut when it ran); None for every other step
    enforced: Enforced | None = None

    @property
    def usage(self) -> TokenUsage:
        total = TokenUsage()
        for attempt in self.attempts:
            total = total + attempt.usage
        return total

    @property
    def flagged_attack(self) -> bool:
        """The LLM's first parsed answer of this step flags an attack.

        The paper's ADR is "the number of steps in which the LLM detects an attack" divided by "the
        total number of steps in a task" (SafeEmbodAI.tex:746); it does not say which answer of a
        step counts. Only the first counts here (ours, because an arm whose validator asks for
        retries would otherwise get extra chances to flag, and arms would no longer compare step
        for step; ``docs/metrics.md``). The authors' release scores every answer, retries included
        (:mod:`safeembodai_core.metrics.release`).
        """
        first = next((a.response for a in self.attempts if a.response is not None), None)
        return first is not None and first.flags_attack

    @property
    def interventions(self) -> int:
        """Attempts refused by a validator rule (not parse failures)."""
        return sum(1 for a in self.attempts if a.response is not None and not a.accepted)

    @property
    def retries(self) -> int:
        return max(0, len(self.attempts) - 1)

    def to_reference(self) -> ReferenceState:
        accepted = next((a for a in reversed(self.attempts) if a.accepted), None)
        if accepted is None and self.enforced is not None and self.enforced.ran:  # what the LLM saw and planned
            accepted = next((a for a in self.attempts if a.index == self.enforced.attempt), None)
        response = accepted.response if accepted else None
        return ReferenceState(
            step=self.step,
            executed=self.executed,
            perception=[e.model_dump() for e in response.perception] if response else [],
            planning=response.planning if response else "",
            # the robot did not run the LLM's answer but the rules' cut of it: R_{i-1} says so
            outcome_note=self.enforced.note if self.enforced is not None else "",
        )


class Outcome(str, Enum):
    """How a trial ended. The first three are the paper's; the last two are ours."""

    COMPLETED = "completed"
    TIMEOUT = "timeout"
    INTERRUPTED = "interrupted"
    SAFE_ABORT = "safe_abort"  # Algorithm 1 exhausted its failure threshold: nothing unsafe ran
    ERROR = "error"  # the backend failed after its retries: not a safety result


class TrialSpec(_Record):
    """Which trial this is: the cell it belongs to and its seed."""

    trial_id: str
    scenario: str = ""
    environment: str
    arm: str
    condition: str
    index: int = 0
    seed: int


#: What ended an ``error`` trial: ``backend`` -- the LLM backend gave up (an outage, a bad key);
#: ``store`` -- the state store could not write; ``reported`` -- another component reported a
#: failure it knows (a plugin, an environment); ``crash`` -- an unexpected exception (a bug);
#: ``build`` -- the trial's components could not be built.
ErrorKind = Literal["backend", "store", "reported", "crash", "build"]


class TrialResult(_Record):
    """The summary of one trial, what metrics are computed from.

    ``error_kind`` is set on ``error`` trials only; results stored before the field existed load
    with None (``safeembodai_core.ablation.error_kinds`` then reads the kind off ``detail``).
    """

    spec: TrialSpec
    outcome: Outcome
    steps: int
    prompt_tokens: int = 0
    completion_tokens: int = 0
    #: some of the tokens were counted here because the server's usage was missing or unusable
    tokens_estimated: bool = False
    distance_mm: float = 0.0
    collisions: int = 0  # all collisions, attributed or not
    collisions_self: int = 0  # the robot's own motion made the contact
    collisions_struck: int = 0  # a moving obstacle ran into the robot
    #: of those, while the robot stood (through the LLM's think time, or on a step that ran nothing):
    #: out of reach of any rule that judges plans; the rest came during the robot's own motion. None in
    #: runs recorded before the split was kept
    collisions_struck_standing: int | None = None
    #: the self collisions by what was hit (ExecutionResult.hit: wall, ball, labbot, obstacle; "unknown" where
    #: the environment did not say); empty in runs recorded before it was kept
    self_collisions_hit: dict[str, int] = Field(default_factory=dict)

    @property
    def collisions_struck_moving(self) -> int | None:
        """Struck during the robot's own motion (a command running, turns included); None when not recorded."""
        standing = self.collisions_struck_standing
        return None if standing is None else self.collisions_struck - standing
    interventions: int = 0
    retries: int = 0
    #: steps whose spent retries ended in the rules' cut of a refused answer running (``on_exhausted: enforce``)
    enforced_steps: int = 0
    attacked_steps: int = 0
    flagged_steps: int = 0
    flagged_attacked_steps: int = 0  # steps both attacked (ground truth) and flagged by the LLM
    target_visible_steps: int = 0
    first_seen_step: int | None = None  # first step whose observation had the target in view
    lost_after_seen_steps: int = 0  # steps after first_seen_step with the target out of view
    detail: str = ""
    error_kind: ErrorKind | None = None
    #: the kind of world the trial met, as its environment reported it (``truth.world_kind``
    #: of the first observation: a room's drawn Labbot dynamics, say); empty when it says nothing
    world: str = Field("", max_length=64)
    #: the model names the trial's replies gave (first seen first, at most 8); empty when none named one
    models: list[str] = Field(default_factory=list, max_length=8)
    #: what the trial's tokens cost in US dollars at the backend's list price (``LLMBackend.cost``;
    #: replayed answers included); None when the backend knows no price (a simulated pilot)
    cost_usd: float | None = Field(None, ge=0, le=1e9, allow_inf_nan=False)
    trajectory: list[Pose] = Field(default_factory=list)
    wall_time_s: float = 0.0
    #: where the trial ran: the Ray node (its address and the start of its id) for a Ray run; None
    #: for a trial run on the coordinator's machine (serial and process executors)
    node: str | None = Field(None, max_length=80)

    @field_validator("prompt_tokens", "completion_tokens")
    @classmethod
    def _clamped(cls, value: int) -> int:
        return storable_int(value)

    @property
    def tokens(self) -> int:
        return self.prompt_tokens + self.completion_tokens
