"""A trial's step timeline for its page: what the LLM saw and was sent, what it answered, what the
guard refused and why, what ran, what it hit, which attacks were injected.

A run folder keeps no sensor readings nor prompts, so the trial is replayed from its recorded
answers (:func:`~safeembodai_core.loop.replay.replay_trial`, no LLM called) to get the prompts and
their images back; a replay that cannot be made (a plugin gone, a world that does not replay) leaves
the page without them and says why, with everything recorded still shown.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from ..models import StepRecord, TrialSpec
from ..models.observation import ImagePart, TextPart
from ..loop.capture import Seen
from .files import safe_name
from .plan_picture import plan_svg

_SUFFIX = {"image/png": "png", "image/jpeg": "jpg"}


@dataclass
class AttemptView:
    number: int
    answer: str
    reasoning: str
    finish_reason: str | None
    model: str | None
    accepted: bool
    parse_error: str | None
    verdicts: list[tuple[str, bool, str]]  # (where, valid, reason)


@dataclass
class StepView:
    step: int
    instruction: str
    sim_time_s: float
    attacks: list[tuple[str, str, str]]  # (kind, channel, payload)
    images: list[tuple[str, str]] = field(default_factory=list)  # (modality, file relative to the page)
    system: str = ""
    user: str = ""
    attempts: list[AttemptView] = field(default_factory=list)
    executed: list[tuple[str, str, bool]] = field(default_factory=list)  # (signal, result, collided)
    waited_collision: str = ""
    enforced: str = ""  # on_exhausted: enforce -- what the rules made of the refused answer (not the LLM's plan)
    plans: str = ""  # the step's plans drawn over its scan (a file relative to the page), when it could be


def _result(item: Any) -> str:
    r = item.result
    moved = f"{r.distance_mm:.0f} mm" if item.signal.command == "straight" else f"{r.angle_deg:.0f} deg"
    said = f": {r.detail}" if r.detail else ""
    hit = f" ({r.collision or 'unattributed'} collision, hit {r.hit or '?'})" if r.collided else ""
    return f"moved {moved}{hit}{said}"


def step_views(records: list[StepRecord], prompts: dict[int, list[Any]] | None, site: Any, image_dir: str,
               image_href: str, scans: dict[int, Any] | None = None, robot_radius_mm: float = 170.0) -> list[StepView]:
    """One view per recorded step; the images of each step's first prompt written into the site's
    ``image_dir`` (linked as ``image_href/<file>``), under names of their own making; with the replay's
    ``scans`` (by step), each step's plans drawn over its scan (:mod:`.plan_picture`)."""
    views = []
    for record in records:
        view = StepView(step=record.step, instruction=record.instruction, sim_time_s=record.sim_time_s,
                        attacks=[(a.kind, a.channel, a.payload) for a in record.attacks])
        sent = (prompts or {}).get(record.step) or []
        if sent:
            first = sent[0]
            view.system = first.system
            view.user = "\n".join(part.text for part in first.user if isinstance(part, TextPart))
            for image in (part for part in first.user if isinstance(part, ImagePart)):
                name = f"step{record.step:03d}-{safe_name(image.name)}.{_SUFFIX.get(image.media_type, 'img')}"
                site.write(f"{image_dir}/{name}", image.data)
                view.images.append((image.name, f"{image_href}/{name}"))
        if scans is not None and record.step in scans and any(a.response is not None for a in record.attempts):
            name = f"step{record.step:03d}-plans.svg"
            site.write(f"{image_dir}/{name}", plan_svg(scans[record.step], record.attempts,
                                                       robot_radius_mm).encode("utf-8"))
            view.plans = f"{image_href}/{name}"
        for attempt in record.attempts:
            view.attempts.append(AttemptView(
                number=attempt.index + 1, answer=attempt.raw_text, reasoning=attempt.reasoning,
                finish_reason=attempt.finish_reason, model=attempt.model, accepted=attempt.accepted,
                parse_error=attempt.parse_error,
                verdicts=[(v.rule + ("" if v.signal_index is None else f" (signal {v.signal_index + 1})"), v.valid,
                           v.reason) for v in attempt.verdicts]))
        view.executed = [(item.signal.describe(), _result(item), item.result.collided) for item in record.executed]
        if record.enforced is not None:
            view.enforced = record.enforced.note
        truth = record.truth
        if truth.collision is not None:
            view.waited_collision = f"{truth.collision} collision while the robot waited: {truth.collision_detail}"
        views.append(view)
    return views


def replayed_prompts(runner: Any, spec: TrialSpec,
                     records: list[StepRecord]) -> tuple[dict[int, list[Any]], dict[int, Any], str]:
    """The prompts of a replay of the trial, each step's scan as the rules read it, and why there are
    none when it could not be replayed."""
    from ..errors import SafeEmbodAIError
    from ..loop.replay import replay_trial

    try:
        capture, _, _ = replay_trial(runner, spec, records)
    except SafeEmbodAIError as error:
        return {}, {}, f"the prompts and images could not be rebuilt: {error}"
    except Exception as error:  # a plugin's bug: the page still shows every record
        return {}, {}, f"the prompts and images could not be rebuilt: {type(error).__name__}: {error}"
    scans = {event.step: event.scan for event in capture.events if isinstance(event, Seen)}
    return capture.prompts, scans, ""
