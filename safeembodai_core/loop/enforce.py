"""``on_exhausted: enforce``: when N retries are spent, run the rules' own cut of the refused answer.

Ours, not the paper's: Algorithm 1 marks a step whose N retries are spent as "mission failed"
(``abort``); ``hold`` skips it. A refusal already says, as data (:class:`~safeembodai_core.models.Advice`),
how much of the refused plan is safe. ``enforce`` applies that advice itself instead of waiting for a
pilot to follow it:

1. the answer cut is the step's **last attempt that parsed and was refused** (a reply that did not
   parse is never executed, nor any part of it; no parsed answer: the step holds);
2. its plan is cut as its refusals allow (:func:`cut_plan`): where a refusal offers a whole
   alternative plan (``step_aside``), that plan; else the signals before the first refused signal,
   that signal shortened to the least ``safe_mm`` (a straight) or ``safe_deg`` (a turn) its refusals
   give -- every refusal of it must give one, at least 1 -- and nothing after it. A refusal that
   asks to ``wait``, says 0, or gives no number drops the refused signal;
3. the cut is judged again by **every** rule, on the context that answer was judged on (with the
   arm's ``fresh_scan``: the reading taken when that answer arrived; no new reading is taken);
4. if it is not empty and every rule passes it, it runs; otherwise the step **holds** (no motion),
   and the trial carries on as with ``hold``.

The step's record says so plainly (:class:`~safeembodai_core.models.Enforced`, ``StepRecord.enforced``):
``accepted`` stays False -- no answer of the LLM passed -- and ``planned`` holds the cut when it ran.
The refused attempts count as interventions as they always do; the enforced step adds none, and is
counted apart (``TrialResult.enforced_steps``). The same function serves the Gymnasium guard, so the
same arm gives the same verdicts and motions there (:mod:`safeembodai_core.integrations.gym.guard`).
"""

from __future__ import annotations

from typing import Callable, Literal, Mapping, Sequence

from ..contracts.components import Validator
from ..models import Attempt, ControlSignal, Enforced, Straight, Verdict
from ..validation.context import ValidationContext, validate_plan


Source = Literal["cut", "step_aside"]


def cut_plan(plan: Sequence[ControlSignal], verdicts: Sequence[Verdict]) -> tuple[list[ControlSignal], Source, str]:
    """The plan ``verdicts``' refusals allow of ``plan``: ``(signals, source, why)``; ``source`` is
    ``step_aside`` or ``cut``, ``why`` says in words what was kept (see the module docstring)."""
    refused = [v for v in verdicts if not v.valid]
    for verdict in sorted(refused, key=lambda v: -1 if v.signal_index is None else v.signal_index):
        if verdict.advice is not None and verdict.advice.step_aside:
            return list(verdict.advice.step_aside), "step_aside", f"the step aside {verdict.rule} offered"
    if not refused:
        return list(plan), "cut", "the plan as it was"
    if any(v.signal_index is None or not 0 <= v.signal_index < len(plan) for v in refused):
        return [], "cut", "a refusal was about the whole plan"
    first = min(v.signal_index for v in refused if v.signal_index is not None)
    kept = list(plan[:first])
    signal = plan[first]
    straight = isinstance(signal, Straight)
    allowed: list[float] = []
    for verdict in (v for v in refused if v.signal_index == first):
        advice = verdict.advice
        value = None if advice is None or advice.wait else (advice.safe_mm if straight else advice.safe_deg)
        if value is None or value < 1:
            what = "asks to wait" if advice is not None and advice.wait else "allows none of it"
            return kept, "cut", f"signal {first + 1} dropped ({verdict.rule} {what})"
        allowed.append(float(value))
    least = min(allowed)
    current = signal.distance if isinstance(signal, Straight) else signal.angle
    if least >= current:  # a refusal that allows the whole signal gives nothing to cut by
        return kept, "cut", f"signal {first + 1} dropped (its refusals allow all of it)"
    field, unit = ("distance", "mm") if straight else ("angle", "deg")
    shorter = signal.model_copy(update={field: least,
                                        "justification": f"cut by the rules to {least:g} {unit}, what they allow"})
    return kept + [shorter], "cut", f"signal {first + 1} cut to {least:g} {unit}"


def last_refused(attempts: Sequence[Attempt]) -> Attempt | None:
    """The step's last attempt that parsed and was refused by a rule (None: no answer parsed)."""
    return next((a for a in reversed(attempts) if a.response is not None and not a.accepted), None)


def enforce(attempts: Sequence[Attempt], judged: Mapping[int, ValidationContext],
            validators: Sequence[tuple[str, Validator]]) -> Enforced:
    """What ``on_exhausted: enforce`` does with a step whose retries are spent: the cut of its last
    parsed, refused attempt, judged again by ``validators`` on ``judged[attempt.index]`` (the context
    that attempt was judged on). See the module docstring."""
    attempt = last_refused(attempts)
    if attempt is None or attempt.index not in judged or not validators:
        return nothing_to_cut()
    assert attempt.response is not None  # last_refused found a parsed one
    context = judged[attempt.index]
    return enforce_cut(attempt.index, list(attempt.response.control), attempt.verdicts,
                       lambda plan: validate_plan(plan, context, validators))


def nothing_to_cut() -> Enforced:
    """The record of a step whose retries were spent with no parsed, judged answer: it holds."""
    return Enforced(note="no answer of the step parsed and was judged: nothing to cut; the step held without moving")


def enforce_cut(index: int, plan: Sequence[ControlSignal], verdicts: Sequence[Verdict],
                judge: Callable[[list[ControlSignal]], list[Verdict]]) -> Enforced:
    """The cut of attempt ``index``'s refused ``plan`` (:func:`cut_plan` of its ``verdicts``), judged
    again by ``judge`` (every rule, on the context the attempt was judged on): it runs when it is not
    empty and passes, else the step holds. The trial loop and the Gymnasium guard both end here."""
    cut, source, why = cut_plan(plan, verdicts)
    where = f"attempt {index + 1}"
    if not cut:
        return Enforced(attempt=index, source=source,
                        note=f"nothing of {where}'s refused plan is safe ({why}); the step held without moving")
    again = judge(cut)
    said = ", ".join(s.describe() for s in cut)
    if not all(v.valid for v in again):
        refusal = next(v for v in again if not v.valid)
        return Enforced(attempt=index, source=source, plan=cut, verdicts=again,
                        note=f"the rules' cut of {where} ({said}; {why}) was refused again ({refusal.line()}); "
                             "the step held without moving")
    return Enforced(attempt=index, source=source, plan=cut, verdicts=again, ran=True,
                    note=f"the LLM's answers were refused; the rules' cut of {where} ran instead: {said} ({why})")
