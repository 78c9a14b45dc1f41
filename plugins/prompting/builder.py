"""The ``jinja`` prompt builder: a :class:`PromptRequest` in, the system prompt Y and user prompt I_i out.

The system template renders the behaviour instruction B = {r, t, b, f, m} of Table I; with
secure prompting on, the security prefix p from ``security/<variant>.j2`` goes first (Y = {B, p});
with it off, p is absent. The response format f is :func:`schema_outline`, generated from the
pydantic response model, so the prompt cannot drift from what the parser accepts.

A security-prefix template may also *set* variables that change the prompt:

* ``fence_instruction = true`` -- the human instruction is fenced between unguessable markers
  (``fence.open`` / ``fence.close`` are passed to the prefix template so it can name them);
* ``reminder = "..."`` -- a line repeated after the untrusted text (the "sandwich" defence);
* ``placement = "end"`` -- p goes at the end of Y instead of the top (the authors' release
  appends it, eyesimLLM ``src/llm/prompt.py:56``); ``"start"`` is the default.

With ``reference_view: last_command`` the user prompt carries only "Last Command:" and the
previous step's signals ("None" at step 1), the authors' release's state (``src/llm/prompt.py:12``).

Untrusted text -- the human instruction and everything in R_{i-1} that an LLM wrote -- is
clipped to a length budget and passed to templates as data only.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace
from typing import Any

import numpy as np

from safeembodai_core.contracts.components import PromptBuilder
from safeembodai_core.models import ImagePart, Prompt, PromptRequest, ReferenceState, Refusal, TextPart
from safeembodai_core.models.prompt import DEFAULT_TASK
from safeembodai_core.models.response import OutlineExamples, schema_outline

from .templates import PromptTemplateError, TemplateSet

IMAGE_ORDER = ("camera_image", "lidar_image")
IMAGE_TITLES = {"camera_image": "Camera Image", "lidar_image": "LiDAR Image"}
_ELLIPSIS = " [...]"


def clip(text: object, limit: int) -> str:
    """``text`` (as a string) cut to ``limit`` characters, marked when cut."""
    text = str(text)
    return text if len(text) <= limit else text[: max(0, limit - len(_ELLIPSIS))] + _ELLIPSIS


def fence_for(text: str, step: int) -> dict[str, str]:
    """Delimiters for spotlighting ``text``: derived from the text itself, so a payload cannot
    contain its own closing marker (it would have to contain its own hash)."""
    salt = 0
    while True:
        tag = hashlib.blake2b(f"{step}:{salt}:{text}".encode(), digest_size=4).hexdigest()
        if tag not in text:
            return {"tag": tag, "open": f"<<data-{tag}>>", "close": f"<</data-{tag}>>"}
        salt += 1


def _result_text(result: Any) -> str:
    if result.collided:
        return f"collided ({result.detail})" if result.detail else "collided"
    if result.stopped:
        return f"stopped ({result.detail})" if result.detail else "stopped"
    if result.distance_mm:
        return f"moved {abs(result.distance_mm):.0f} mm"
    if result.angle_deg:
        return f"turned {abs(result.angle_deg):.0f} deg"
    return result.detail or "no motion"


def _sample_request() -> PromptRequest:
    """A request that exercises every branch of the built-in templates (used as a dry run)."""
    from safeembodai_core.models import ExecutedSignal, ExecutionResult, Modalities, Turn

    image = ImagePart("camera_image", b"", width=320, height=240)
    lidar = ImagePart("lidar_image", b"", width=240, height=240)
    turn = Turn(command="turn", direction="left", angle=10.0)
    state = ReferenceState(
        step=1, executed=[ExecutedSignal(signal=turn, result=ExecutionResult(angle_deg=10.0))],
        perception=[{"input": "camera_image", "result": "seen", "is_attack": True}],
        planning="plan", outcome_note="note",
    )
    return PromptRequest(
        instruction="instruction", step=2, reference_state=state, failures=("failure",),
        modalities=Modalities(images={"camera_image": image, "lidar_image": lidar}, texts={"camera_text": "text"}),
    )


#: How the response outline shows distances and angles (see :func:`schema_outline`): values drawn
#: per prompt, chosen with ``bench/real_model.py outline`` (docs/local_models.md, "The outline's example
#: values": SmolLM2 copied the fixed 200 / 45 in 36 of 47 signals).
OUTLINE_EXAMPLES: OutlineExamples = "seeded"


def outline_rng(request: PromptRequest) -> np.random.Generator:
    """The generator of a ``seeded`` outline: seeded from the step's own inputs (step, instruction,
    texts, images), so the same trial seed gives the same prompt, and prompts of different steps
    or scenes show different example values."""
    digest = hashlib.blake2b(digest_size=8)
    m = request.modalities
    for part in (str(request.step), request.instruction, *(f"{k}={m.texts[k]}" for k in sorted(m.texts))):
        digest.update(part.encode("utf-8", "surrogatepass") + b"\0")
    for name in sorted(m.images):
        digest.update(name.encode() + b"\0" + m.images[name].data + b"\0")
    return np.random.default_rng(int.from_bytes(digest.digest(), "big"))


class JinjaPromptBuilder(PromptBuilder):
    """Renders Table I (system) and I_i (user) from sandboxed templates; see the module docstring."""

    def __init__(self, options: Any, outline_examples: OutlineExamples = OUTLINE_EXAMPLES) -> None:
        self.options = options
        self.outline_examples = outline_examples
        self.templates = TemplateSet(options.template_dir)
        self._outlines: dict[Any, str] = {}
        # Fail at build time, naming the file, rather than in the middle of a trial.
        self.templates.load(options.system_template)
        self.templates.load(options.user_template)
        self.build(_sample_request())
        self.build(replace(_sample_request(), reference_view="last_command"))

    def _outline(self, request: PromptRequest) -> str:
        """The response outline for the step's limits (its example values lie inside them)."""
        if self.outline_examples == "seeded":
            return schema_outline(request.limits, "seeded", outline_rng(request))
        if request.limits not in self._outlines:
            self._outlines[request.limits] = schema_outline(request.limits, self.outline_examples)
        return self._outlines[request.limits]

    # -- the parts of the prompt ----------------------------------------------------------------

    def security_prefix_variants(self) -> list[str]:
        return self.templates.variants()

    def security_prefix(self, variant: str) -> str:
        """p of ``variant`` rendered alone (its task the default one); a variant that fences the human
        instruction names markers only a prompt built here has, so it is refused."""
        name = self.templates.security_template(variant)
        text, exported = self.templates.module(name, {"fence": fence_for("", 0), "task": DEFAULT_TASK})
        if exported.get("fence_instruction", False):
            raise PromptTemplateError(f"security prefix {variant!r} fences the human instruction between markers "
                                      "of a prompt built here: it cannot stand alone")
        return text

    def _security(self, request: PromptRequest) -> tuple[str, dict[str, Any] | None, str, str]:
        if request.security_prefix is None:
            return "", None, "", "start"
        name = self.templates.security_template(request.security_prefix)
        fence = fence_for(request.instruction, request.step)
        text, exported = self.templates.module(name, {"fence": fence, "task": request.task})
        wants_fence = bool(exported.get("fence_instruction", False))
        reminder = str(exported.get("reminder", "") or "").strip()
        placement = exported.get("placement", "start")
        if placement not in ("start", "end"):
            raise PromptTemplateError(f"prompt template {name}: placement must be 'start' or 'end', got {placement!r}")
        return text, (fence if wants_fence else None), reminder, placement

    @staticmethod
    def _last_command(request: PromptRequest) -> str | None:
        """The release's "Last Command:" text: the previous step's signals, or "None"."""
        if request.reference_view != "last_command":
            return None
        state = request.reference_state
        if state is None or not state.executed:
            return "None"
        return ", ".join(item.signal.describe() for item in state.executed)

    def _reference(self, state: ReferenceState | None) -> dict[str, Any] | None:
        if state is None:
            return None
        limit = self.options.max_reference_chars
        notes = {}
        flagged = []
        for entry in state.perception:
            name = str(entry.get("input", ""))
            if entry.get("is_attack") is True:
                flagged.append(clip(name, 40))
            if name == "camera_image" and entry.get("result"):
                notes["camera"] = clip(entry["result"], limit)
        return {
            "step": state.step,
            "executed": [
                {"signal": item.signal.describe(), "result": clip(_result_text(item.result), limit)}
                for item in state.executed
            ],
            "planning": clip(state.planning, limit) if state.planning else "",
            "camera": notes.get("camera", ""),
            "flagged": flagged,
            "note": clip(state.outcome_note, limit) if state.outcome_note else "",
        }

    def _failures(self, failures: tuple[str, ...]) -> tuple[list[str], int]:
        keep = self.options.max_failures
        recent = list(failures[-keep:]) if keep else []
        return [clip(line, self.options.max_failure_chars) for line in recent], len(failures) - len(recent)

    def _shown(self, request: PromptRequest, shown: int) -> tuple[Refusal, ...]:
        """The refusals of the failure lines the prompt shows (the last ``shown``), when the request
        gave one per line; none otherwise (a request with reasons only: nothing to hand on as data).
        A line cut shorter than where its advice's words end (``Refusal.advice_end``) is handed on
        without its advice: the prompt no longer says it."""
        if not shown or len(request.refusals) != len(request.failures):
            return ()
        kept = self.options.max_failure_chars - len(_ELLIPSIS)
        refusals = []
        for line, refusal in zip(request.failures[-shown:], request.refusals[-shown:]):
            cut = len(line) > self.options.max_failure_chars
            if cut and refusal.advice is not None and (refusal.advice_end is None or refusal.advice_end > kept):
                refusal = refusal.model_copy(update={"advice": None})
            refusals.append(refusal)
        return tuple(refusals)

    # -- PromptBuilder ------------------------------------------------------------------------

    def build(self, request: PromptRequest) -> Prompt:
        m = request.modalities
        prefix, fence, reminder, placement = self._security(request)
        images = [name for name in IMAGE_ORDER if name in m.images]
        images += sorted(name for name in m.images if name not in IMAGE_ORDER)
        camera = m.images.get("camera_image")
        inputs = ["human_instruction", *images, *sorted(m.texts)]
        last_command = self._last_command(request)
        reference = self._reference(request.reference_state) if last_command is None else None
        system = self.templates.render(self.options.system_template, {
            "task": request.task,
            "security_prefix": prefix,
            "security_placement": placement,
            "has_camera_image": camera is not None,
            "camera_size": f"{camera.width}x{camera.height}" if camera is not None and camera.width else "",
            "has_lidar_image": "lidar_image" in m.images,
            "other_images": [name for name in images if name not in IMAGE_ORDER],
            "texts": sorted(m.texts),
            "has_reference": reference is not None,
            "has_last_command": last_command is not None,
            "inputs": inputs,
            "response_outline": self._outline(request),
            "max_distance_mm": f"{request.limits.max_distance_mm:g}",
            "max_angle_deg": f"{request.limits.max_angle_deg:g}",
            "max_signals": request.limits.max_signals,
        })
        failures, omitted = self._failures(request.failures)
        user = self.templates.render(self.options.user_template, {
            "step": request.step,
            "instruction": clip(request.instruction, self.options.max_instruction_chars),
            "fence": fence,
            "reminder": reminder,
            "texts": [m.texts[name] for name in sorted(m.texts)],
            "reference": reference,
            "last_command": last_command,
            "failures": failures,
            "omitted_failures": omitted,
            "images": [IMAGE_TITLES.get(name, name.replace("_", " ")) for name in images],
        })
        sections = {"role", "task", "capabilities", "response_format", "methods", "human_instruction"}
        sections.update(images)
        sections.update(m.texts)
        if prefix:
            sections.add("security_prefix")
        if fence is not None:
            sections.add("fenced_instruction")
        if reference is not None:
            sections.add("reference_state")
        if last_command is not None:
            sections.add("last_command")
        if failures:
            sections.add("failures")
        parts: list[TextPart | ImagePart] = [TextPart("user", user)]
        parts.extend(m.images[name] for name in images)
        shown = self._shown(request, len(failures))
        return Prompt(system=system, user=tuple(parts), sections=frozenset(sections), refusals=shown,
                      refusals_left_out=omitted if shown else 0)
