"""A recorded trial run again from its answers, to see what the robot saw without calling any LLM.

A run folder keeps every step's answers, verdicts and executed commands, but not the sensor
readings (a scan and two images per step would multiply its size). :func:`replay_trial` rebuilds
them: the trial's components from the recorded scenario, the world reset to the trial's seed, and a
backend (:class:`RecordedAnswers`) that hands back, in order, the replies the LLM gave. Everything
else -- attackers, perception, prompts, Algorithm 1, the rules, the physics -- runs as it ran, so a
deterministic world gives the same trial again. That is checked, not assumed: every replayed step
must agree with the recorded one (each attempt's acceptance and verdicts, the rules' cut an arm with
``on_exhausted: enforce`` ran or held, each executed command and its result, the poses), or
:class:`ReplayDiverged` names the first step that did not.
"""

from __future__ import annotations

import math
from typing import Any

from ..contracts.components import BackendReply, LLMBackend
from ..errors import BackendError, SafeEmbodAIError
from ..models import StepRecord, TrialResult, TrialSpec
from ..plugin.refs import ref
from .capture import TrialCapture
from .trial import TrialParts, run_trial

#: Poses and distances agree when within this many mm (degrees for headings).
TOLERANCE = 1e-3


class ReplayDiverged(SafeEmbodAIError):
    """The replayed trial did not do what the recorded one did (names the step and what differed)."""


class RecordedAnswers(LLMBackend):
    """Hands back the recorded replies of a trial, attempt by attempt; fails when they run out."""

    def __init__(self, records: list[StepRecord]) -> None:
        self.replies = [attempt for record in records for attempt in record.attempts]
        self.calls = 0

    def complete(self, prompt: Any, rng: Any) -> BackendReply:
        if self.calls >= len(self.replies):
            raise BackendError(f"replay: the recording holds no answer after {len(self.replies)}")
        attempt = self.replies[self.calls]
        self.calls += 1
        return BackendReply(text=attempt.raw_text, usage=attempt.usage, latency_s=attempt.latency_s,
                            model=attempt.model or "", finish_reason=attempt.finish_reason,
                            reasoning=attempt.reasoning or None, choices=attempt.choices, origin=attempt.origin)


def _close(a: float, b: float) -> bool:
    return math.isclose(a, b, abs_tol=TOLERANCE)


def _same_pose(a: Any, b: Any) -> bool:
    if a is None or b is None:
        return a is b
    return _close(a.x_mm, b.x_mm) and _close(a.y_mm, b.y_mm) and _close(a.heading_deg, b.heading_deg)


def difference(recorded: StepRecord, replayed: StepRecord | None) -> str | None:
    """How ``replayed`` differs from ``recorded`` (None when they agree on everything that moved the robot)."""
    if replayed is None:
        return "the replay ended before this step"
    if recorded.instruction != replayed.instruction:
        return "the instruction differs (an attacker or the scenario changed)"
    if [(a.kind, a.channel, a.payload) for a in recorded.attacks] != \
            [(a.kind, a.channel, a.payload) for a in replayed.attacks]:
        return "the attacks injected differ"
    if len(recorded.attempts) != len(replayed.attempts):
        return f"{len(recorded.attempts)} attempts recorded, {len(replayed.attempts)} replayed"
    for old, new in zip(recorded.attempts, replayed.attempts):
        if old.accepted != new.accepted or (old.parse_error is None) != (new.parse_error is None):
            def said(attempt: Any) -> str:
                return "not read" if attempt.parse_error is not None else "accepted" if attempt.accepted else "refused"

            return f"attempt {old.index + 1}: recorded {said(old)}, replayed {said(new)}"
        if [(v.rule, v.valid, v.signal_index) for v in old.verdicts] != \
                [(v.rule, v.valid, v.signal_index) for v in new.verdicts]:
            return f"attempt {old.index + 1}: the rules' verdicts differ"
    was, now = recorded.enforced, replayed.enforced  # on_exhausted: enforce -- the rules' cut, judged again
    if (was is None) != (now is None) or (was is not None and now is not None and (
            was.attempt != now.attempt or was.ran != now.ran or was.plan != now.plan
            or [(v.rule, v.valid, v.signal_index) for v in was.verdicts] !=
            [(v.rule, v.valid, v.signal_index) for v in now.verdicts])):
        def told(enforced: Any) -> str:
            return "no cut" if enforced is None else enforced.note or "a cut"

        return f"the rules' cut differs: recorded {told(was)}; replayed {told(now)}"
    if not _same_pose(recorded.pose_before, replayed.pose_before):
        return f"the robot started the step at {replayed.pose_before}, recorded {recorded.pose_before}"
    if len(recorded.executed) != len(replayed.executed):
        return f"{len(recorded.executed)} commands executed in the recording, {len(replayed.executed)} in the replay"
    for index, (done, redone) in enumerate(zip(recorded.executed, replayed.executed), start=1):
        a, b = done.result, redone.result
        if done.signal != redone.signal or a.collided != b.collided or a.collision != b.collision or \
                not _close(a.distance_mm, b.distance_mm) or not _close(a.angle_deg, b.angle_deg):
            return f"command {index} ({done.signal.describe()}) did something else: recorded {a.detail or 'ran'}, " \
                   f"replayed {b.detail or 'ran'}"
    if not _same_pose(recorded.pose_after, replayed.pose_after):
        return f"the robot ended the step at {replayed.pose_after}, recorded {recorded.pose_after}"
    return None


def replay_trial(runner: Any, spec: TrialSpec, records: list[StepRecord]) -> tuple[TrialCapture, list[StepRecord],
                                                                                    TrialResult]:
    """Run ``spec`` again with ``records``' answers through ``runner``'s components (a
    :class:`~safeembodai_core.runs.runner.ScenarioRunner` of the recorded scenario); return what it
    captured, the replayed step records and result. Raises :class:`ReplayDiverged` when a step
    does not agree with its record."""
    if not records:
        raise ReplayDiverged(f"trial {spec.trial_id} has no recorded step to replay")
    built = runner.parts(spec, backend=RecordedAnswers(records))
    capture = TrialCapture()
    environment, perception = capture.wrap(built.environment, built.perception)
    parts = TrialParts(environment=environment, perception=perception,
                       prompt_builder=capture.wrap_prompts(built.prompt_builder),
                       state=runner.builder.state_store(ref("memory")), backend=built.backend,
                       validators=built.validators, attackers=built.attackers)
    result = run_trial(spec, parts, runner.settings(spec.arm))
    replayed = parts.state.steps(spec.trial_id)
    by_step = {record.step: record for record in replayed}
    for record in records:
        differs = difference(record, by_step.get(record.step))
        if differs is not None:
            raise ReplayDiverged(f"trial {spec.trial_id}: the replay differs from the recording at step {record.step}: "
                                 f"{differs} (the world or a component is not deterministic, or changed since the run)")
    kept = {record.step for record in records}
    return capture, [r for r in replayed if r.step in kept], result
