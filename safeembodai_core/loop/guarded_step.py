"""Algorithm 1: ask the LLM, parse, validate, and retry with the failures fed back.

The answer of attempt j is executed only if it parses into the response schema (always
required: the robot cannot execute anything else) and, when safety validation is on, every
control signal passes every rule. Otherwise the reasons are handed to the prompt builder for
attempt j+1, up to the failure threshold N. With N spent the step has no executable answer.

Parsing is the strict reading of the whole reply, :func:`~safeembodai_core.models.read_reply`, the
same as :meth:`~safeembodai_core.guard.guard.Guard.check_reply`, the Gymnasium env's and the Inspect
solver's: an answer the provider did not end normally (cut off at the token limit, filtered), a
reply with two choices or a second plan in its reasoning is refused like any malformed one,
refusal reasons quote the LLM's own words as JSON strings, and nothing raised while reading an
answer ends the trial. The attempt's record keeps the reply's text, reasoning, finish reason (as
sent), number of choices and origin.
"""

from __future__ import annotations

import time
from dataclasses import replace
from typing import Callable, Sequence


from .. import seeds
from ..contracts.components import LLMBackend, PromptBuilder, Validator
from ..errors import BackendError
from ..models import Attempt, LLMResponse, PromptRequest, Refusal, ResponseParseError, TokenUsage, read_reply
from ..models.reply import as_reply, finish_reason_text
from ..validation.context import ValidationContext, validate_plan

from ..logs import get_logger, redact

log = get_logger(__name__)

MAX_STORED_TEXT = 16_000


def _stored(text: object) -> str:
    """Untrusted reply text as recorded: redacted before the cut, so the cut can never leave part
    of a secret readable; anything that is not text records as empty (the reading refuses it)."""
    return redact(text)[:MAX_STORED_TEXT] if isinstance(text, str) else ""


def _count(value: object) -> int | None:
    return value if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 2**31 else None


def _one_line(text: str) -> str:
    """Reasons can echo LLM-written text (a parser error quotes the bad value): keep each on one
    line so it cannot pose as a section of the next prompt."""
    return " ".join(text.split())


def feedback(index: int, attempt: Attempt) -> list[str]:
    """The failure lines refused ``attempt`` (index ``index`` in its step) adds to the retry prompt
    (Algorithm 1's feedback): ``attempt K (refused plan: ...): reason``, one per reason."""
    return [_one_line(f"attempt {index + 1}{_refused(attempt)}: {reason}") for reason in attempt.failures()]


def _refused(attempt: Attempt) -> str:
    if attempt.response is None or not attempt.response.control:
        return ""
    return " (refused plan: " + ", ".join(s.describe() for s in attempt.response.control) + ")"


def feedback_refusals(index: int, attempt: Attempt) -> list[Refusal]:
    """:meth:`Attempt.refusals`, each with where in its failure line (:func:`feedback`) the advice's words end."""
    refusals = attempt.refusals()
    if attempt.parse_error is not None:
        return refusals
    refused = [v for v in attempt.verdicts if not v.valid]
    marked = []
    for verdict, refusal in zip(refused, refusals):
        advice = verdict.advice
        if advice is not None and advice.words_end is not None:
            where = "" if verdict.signal_index is None else f" (signal {verdict.signal_index + 1})"
            said = f"attempt {index + 1}{_refused(attempt)}: {verdict.rule}{where}: {verdict.reason[:advice.words_end]}"
            refusal = refusal.model_copy(update={"advice_end": len(_one_line(said))})
        marked.append(refusal)
    return marked


def decide(
    request: PromptRequest,
    *,
    builder: PromptBuilder,
    backend: LLMBackend,
    validators: Sequence[tuple[str, Validator]],
    context: ValidationContext,
    failure_threshold: int,
    seed: int,
    fresh: Callable[[], ValidationContext] | None = None,
    ended: Callable[[], bool] | None = None,
    judged: dict[int, ValidationContext] | None = None,
    retrying: Callable[[], None] = lambda: None,
) -> tuple[list[Attempt], LLMResponse | None]:
    """Run Algorithm 1 for one step; return every attempt and the accepted answer (or None).

    ``validators`` empty means safety validation is off. ``fresh`` (an arm's ``fresh_scan``) gives
    the context as the world reads when an answer has arrived; each answer that parses is judged
    on it, read anew; ``ended`` says the world has ended meanwhile (a mover struck the robot while
    the LLM thought): no retry follows a refusal then. A
    :class:`~safeembodai_core.errors.BackendError` from the backend propagates to the trial, its
    ``spent`` grown by the usage of the step's attempts answered before it (nothing paid is lost).
    ``judged``, when given, receives the context each judged attempt was judged on, by attempt index
    (what ``on_exhausted: enforce`` judges the cut on, :mod:`~safeembodai_core.loop.enforce`).
    ``retrying`` is called before each retry's call (the environment's
    :meth:`~safeembodai_core.contracts.components.Environment.another_call`: a world that charges each call's time).
    """
    attempts: list[Attempt] = []
    failures: list[str] = []
    refusals: list[Refusal] = []  # the same, as data (Attempt.refusals), one per line
    for index in range(failure_threshold + 1):
        if index:
            retrying()
        prompt = builder.build(replace(request, failures=tuple(failures), refusals=tuple(refusals)))
        rng = seeds.rng(seed, "backend", request.step, index)
        # a backend that decodes under the limits or varies retries learns the attempt (None: nothing prepared)
        sampling = backend.prepare_attempt(index=index, limits=request.limits, rng=rng)
        started = time.perf_counter()
        try:
            reply = as_reply(backend.complete(prompt, rng))
        except BackendError as error:  # the step's answered attempts were paid: the trial counts them
            error.spent = sum((a.usage for a in attempts), error.spent or TokenUsage()) if attempts else error.spent
            raise
        latency = reply.latency_s or (time.perf_counter() - started)
        attempt = Attempt(index=index, raw_text=_stored(reply.text), reasoning=_stored(reply.reasoning),
                          choices=_count(reply.choices), origin=_stored(reply.origin) or None,
                          model=_stored(reply.model)[:200] or None,
                          usage=reply.usage, latency_s=latency, finish_reason=finish_reason_text(reply.finish_reason),
                          sampling=sampling or None)
        try:
            # The one strict reading of the whole reply (shared with Guard.check_reply); it raises
            # nothing else, so no answer, however hostile or cut off, can end the trial.
            response = read_reply(reply, request.limits)
        except ResponseParseError as error:
            attempt.parse_error = str(error)
        else:
            attempt.response = response
            if validators:
                judging = fresh() if fresh else context
                attempt.verdicts = validate_plan(response.control, judging, validators)
                if judged is not None:
                    judged[index] = judging
        attempts.append(attempt)
        if attempt.accepted:
            return attempts, attempt.response
        log.info("step.refused", step=request.step, attempt=index, reasons=attempt.failures())
        if ended is not None and ended():
            break  # nothing can be executed any more: another call would be paid for nothing
        failures.extend(feedback(index, attempt))
        refusals.extend(feedback_refusals(index, attempt))
    return attempts, None
