"""The guarded loop's LLM calls, made through Inspect's model: :class:`InspectBackend`.

The loop (:func:`~safeembodai_core.loop.run_trial`) is synchronous; Inspect's
``Model.generate`` is a coroutine on Inspect's event loop. The solver runs the whole trial in a
worker thread (``anyio.to_thread.run_sync``, which copies the sample's context into it) and this
backend hands each call back to the event loop with ``asyncio.run_coroutine_threadsafe``, then
blocks the worker until the answer is there. The call runs in the sample's context: its
transcript (a model event per call), ``--max-connections``, retries, ``--cache``, token accounting.
The event loop is never blocked by the simulator, and there is no second copy of the loop.

Not ``anyio.from_thread.run``: that puts the call in the sample's cancel scope, and a sample
stopped by ``--time-limit`` then never got its call back (Inspect's generate spun in the
cancelled scope). Here the solver, when its sample is stopped, sets :attr:`InspectBackend.stop`
and leaves; the call in flight finishes on its own, and the next one raises
:class:`BackendError`, which ends the trial (its world goes back to the pool). Under Inspect's
trio backend (no asyncio loop) calls go through ``anyio.from_thread.run``.

A prompt becomes a system message and one user message (text and images in the prompt's
order). The user message's ``metadata["safeembodai"]`` carries what Inspect's messages cannot
say (which sections the prompt has, the modality names, the refusals as data, the state of the
seeded generator the loop handed to this call): providers ignore it; the simulated pilot
(:mod:`.provider`) reads it to see exactly the prompt and dice ``safeembodai ablate`` gives it.
"""

from __future__ import annotations

import asyncio
import base64
import json
import threading
import time
from typing import Any

import numpy as np

from ...contracts.components import BackendReply, LLMBackend
from ...errors import BackendError
from ...models import ImagePart, Prompt, Refusal, TextPart, TokenUsage
from ...models.chat_completion import counted_usage, read_usage, said_usage, usage_believable
from ...models.reply import CLIPPED, envelope_error_text
from ...models.token_estimate import estimated_usage
from ...trust.text import one_line

#: The key of the user message's metadata that carries the prompt's own facts.
META = "safeembodai"

#: Inspect's stop reasons in the words Algorithm 1 reads (only ``stop`` is a normal end: an answer
#: cut off, filtered or calling tools is never executed). ``unknown`` stays ``unknown`` (refused):
#: Inspect's providers say it for a reason they could not map as well as for none.
_STOP_REASONS: dict[str, str | None] = {"stop": "stop", "max_tokens": "length", "model_length": "length",
                                        "content_filter": "content_filter", "tool_calls": "tool_calls"}
#: The ``stop_details.type`` by which ``safeembodai/<backend>`` says "the backend reported no reason".
NOT_REPORTED = "not_reported"
#: The ``stop_details.type`` by which it says "the backend refused the reply as a whole" (the
#: explanation is the refusal, handed back as the reply's ``envelope_error``).
REFUSED_REPLY = "refused_reply"


def rng_state(rng: np.random.Generator) -> dict[str, Any]:
    """The generator's state as JSON-safe data (its 128-bit numbers as decimal strings)."""
    def text(value: Any) -> Any:
        if isinstance(value, dict):
            return {key: text(item) for key, item in value.items()}
        return str(value) if isinstance(value, int) and not isinstance(value, bool) else value
    return text(rng.bit_generator.state)


def rng_from_state(state: dict[str, Any]) -> np.random.Generator:
    """The generator :func:`rng_state` described, at the same point of its stream."""
    def number(value: Any) -> Any:
        if isinstance(value, dict):
            return {key: number(item) for key, item in value.items()}
        return int(value) if isinstance(value, str) and value.lstrip("-").isdigit() else value
    kind = getattr(np.random, state["bit_generator"])
    generator = np.random.Generator(kind())
    generator.bit_generator.state = number(state)
    return generator


def prompt_messages(prompt: Prompt, rng: np.random.Generator | None = None, detail: str = "low") -> list[Any]:
    """``prompt`` as Inspect chat messages (system, then user); see the module docstring."""
    from inspect_ai.model import ChatMessageSystem, ChatMessageUser, ContentImage, ContentText

    content: list[Any] = []
    parts: list[dict[str, Any]] = []
    for part in prompt.user:
        if isinstance(part, ImagePart):
            url = f"data:{part.media_type};base64,{base64.b64encode(part.data).decode('ascii')}"
            content.append(ContentImage(image=url, detail=detail))  # type: ignore[arg-type]
            parts.append({"name": part.name, "width": part.width, "height": part.height})
        else:
            content.append(ContentText(text=part.text))
            parts.append({"name": part.name})
    meta: dict[str, Any] = {"sections": sorted(prompt.sections), "parts": parts}
    if prompt.refusals:  # the failures section as data, for a simulated pilot (Prompt.refusals)
        meta["refusals"] = [refusal.model_dump(mode="json") for refusal in prompt.refusals]
        meta["refusals_left_out"] = prompt.refusals_left_out
    if rng is not None:
        meta["rng"] = rng_state(rng)
    messages: list[Any] = [ChatMessageSystem(content=prompt.system)] if prompt.system else []
    messages.append(ChatMessageUser(content=content, metadata={META: meta}))
    return messages


def prompt_from_messages(messages: list[Any]) -> tuple[Prompt, np.random.Generator | None]:
    """The prompt and generator :func:`prompt_messages` sent (best effort for other messages:
    no sections, parts named by kind, no generator)."""
    system = "\n\n".join(m.text for m in messages if m.role == "system")
    users = [m for m in messages if m.role == "user"]
    user = users[-1] if users else None
    meta = ((user.metadata or {}).get(META) or {}) if user is not None else {}
    content = [] if user is None else ([user.content] if isinstance(user.content, str) else list(user.content))
    described = meta.get("parts") or []
    parts: list[TextPart | ImagePart] = []
    for index, item in enumerate(content):
        about = described[index] if index < len(described) else {}
        if isinstance(item, str) or getattr(item, "type", "") == "text":
            parts.append(TextPart(name=about.get("name", "text"), text=item if isinstance(item, str) else item.text))
        elif getattr(item, "type", "") == "image":
            header, _, data = item.image.partition(",")
            media_type = header.removeprefix("data:").split(";")[0] or "image/png"
            parts.append(ImagePart(name=about.get("name", "image"), data=base64.b64decode(data), media_type=media_type,
                                   width=about.get("width", 0), height=about.get("height", 0)))
    prompt = Prompt(system=system, user=tuple(parts), sections=frozenset(meta.get("sections", ())),
                    refusals=_refusals(meta.get("refusals")), refusals_left_out=_count(meta.get("refusals_left_out")))
    state = meta.get("rng")
    return prompt, (rng_from_state(state) if state else None)


def _refusals(value: Any) -> tuple[Refusal, ...]:
    """The refusals :func:`prompt_messages` put in the metadata; none when they do not validate."""
    try:
        return tuple(Refusal.model_validate(item) for item in value) if isinstance(value, list) else ()
    except ValueError:  # pydantic's ValidationError: not ours, so nothing to read as data
        return ()


def _count(value: Any) -> int:
    return value if isinstance(value, int) and not isinstance(value, bool) and value >= 0 else 0


def _sent_finish_reason(stop_details: Any) -> str | None:
    """The finish reason ``safeembodai/<backend>`` crossed as :data:`ABNORMAL_STOP`, as the backend sent it
    (a JSON string in ``stop_details``, type ``finish_reason``); None when that is not what it holds."""
    if getattr(stop_details, "type", None) != "finish_reason":
        return None
    try:
        sent = json.loads(str(getattr(stop_details, "explanation", "")).removesuffix(CLIPPED))
    except ValueError:
        return None
    return sent if isinstance(sent, str) else None


def finish_reason(stop_reason: Any, stop_details: Any = None) -> str | None:
    """Inspect's stop reason in the words Algorithm 1 reads (:data:`_STOP_REASONS`).

    ``unknown`` is refused: Inspect's own providers give it both when the provider said nothing and
    when it said something Inspect has no name for (an ``error``, say), so it cannot be read as a
    normal end. Only ``safeembodai/<backend>``'s ``unknown`` with ``stop_details`` of type
    :data:`NOT_REPORTED` -- a backend that reports no reason, as under ``ablate`` -- is "not
    reported" (None: accepted unless the contract requires a reason). A reason Inspect does not
    define is passed on as it came, and :func:`~safeembodai_core.models.read_reply` refuses it.
    """
    if stop_reason is None:
        return None
    reason = str(getattr(stop_reason, "value", stop_reason))
    if reason == "unknown" and getattr(stop_details, "type", None) == NOT_REPORTED:
        return None
    sent = _sent_finish_reason(stop_details)
    if sent is not None:  # an unusual reason the backend sent: read back as sent, refused in the same words
        return sent
    return _STOP_REASONS.get(reason, reason)


def reasoning_text(message: Any) -> str | None:
    """The reasoning of an Inspect message: the text of its ``ContentReasoning`` parts, or None.

    A part's readable text is its ``reasoning`` (and its ``summary``, when it has one too); a
    *redacted* part keeps an opaque, encrypted blob or signature in ``reasoning``, which holds
    nothing to read, so only its ``summary`` (the readable text some providers send with it)
    counts. All of it is read for a second plan, as a provider's ``reasoning_content`` is.
    """
    content = getattr(message, "content", None)
    if content is None or isinstance(content, str):
        return None
    texts: list[str] = []
    for part in content:
        if getattr(part, "type", "") != "reasoning":
            continue
        summary = getattr(part, "summary", None)
        if not getattr(part, "redacted", False) and getattr(part, "reasoning", None):
            texts.append(str(part.reasoning))
        if summary:
            texts.append(str(summary))
    return "\n".join(texts) if texts else None


def output_usage(output: Any, prompt: Prompt | None, detail: str = "low") -> TokenUsage:
    """Inspect's ``ModelUsage`` of ``output`` read as a server's usage is (:func:`read_usage`: two
    whole, non-negative counts, and believable); anything else -- none, a zero for a request, a
    negative or fractional count -- is the call counted here (:func:`estimated_usage`), never 0 nor
    less than what it said (:func:`counted_usage`).
    Counts ``safeembodai/<backend>`` made itself stay marked estimated (the output's metadata)."""
    usage = getattr(output, "usage", None)
    counts = None if usage is None else {"prompt_tokens": getattr(usage, "input_tokens", None),
                                         "completion_tokens": getattr(usage, "output_tokens", None)}
    read = read_usage(counts)
    text = output.completion if isinstance(output.completion, str) else ""
    if read is not None and usage_believable(read, text):
        marked = ((getattr(output, "metadata", None) or {}).get(META) or {}).get("usage_estimated") is True
        return read.model_copy(update={"estimated": True}) if marked else read
    return counted_usage(said_usage(counts), estimated_usage(prompt or Prompt(system="", user=()), text, detail))


def backend_reply(output: Any, started: float, prompt: Prompt | None = None, detail: str = "low") -> BackendReply:
    """Inspect's ``ModelOutput`` as the loop's :class:`BackendReply`: the whole reply.

    The text is the first choice's text parts (``output.completion``), ``choices`` how many
    choices the output held (anything but one is refused), ``reasoning`` the first choice's
    reasoning parts (:func:`reasoning_text`), ``finish_reason`` its stop reason
    (:func:`finish_reason`), ``usage`` :func:`output_usage` (``prompt``: what was sent, for the count);
    a reply ``safeembodai/<backend>`` marks refused as a whole (:data:`REFUSED_REPLY`) comes back with
    its refusal as ``envelope_error``, so the reasons read as under ``ablate``.
    """
    first = output.choices[0] if output.choices else None
    details = getattr(first, "stop_details", None)
    refused = envelope_error_text(getattr(details, "explanation", None) or "refused by the backend") \
        if getattr(details, "type", None) == REFUSED_REPLY else None
    return BackendReply(
        text=output.completion,
        usage=output_usage(output, prompt, detail),
        latency_s=output.time or (time.perf_counter() - started),
        model=output.model or "",
        finish_reason=None if first is None else finish_reason(first.stop_reason, getattr(first, "stop_details", None)),
        reasoning=None if first is None else reasoning_text(first.message),
        choices=len(output.choices),
        envelope_error=refused,
    )


def _spent(error: BaseException | None) -> TokenUsage | None:
    """What a failed call paid, as ``safeembodai/<backend>``'s :class:`BackendError` says, through
    whatever Inspect wrapped it in (its cause or context chain); None when nothing says."""
    seen = 0
    while error is not None and seen < 16:
        spent = getattr(error, "spent", None)
        if isinstance(spent, TokenUsage):
            return spent
        error, seen = error.__cause__ or error.__context__, seen + 1
    return None


class InspectBackend(LLMBackend):
    """An :class:`LLMBackend` whose every call is ``model.generate`` on Inspect's event loop.

    Must be called from a thread started by ``anyio.to_thread.run_sync`` (the solver's worker).
    A call Inspect gives up on (after its retries), or a sample limit reached, raises
    :class:`BackendError`: the trial ends ``error`` (kind ``backend``), as with any backend.
    """

    def __init__(self, model: Any, detail: str = "low", loop: asyncio.AbstractEventLoop | None = None) -> None:
        self.model = model
        self.detail = detail
        self.loop = loop
        self.stop = threading.Event()

    def complete(self, prompt: Prompt, rng: np.random.Generator) -> BackendReply:
        if self.stop.is_set():
            raise BackendError("the sample was stopped (an Inspect limit or cancellation): no further model calls")
        messages = prompt_messages(prompt, rng, self.detail)
        started = time.perf_counter()
        try:
            if self.loop is not None:
                output = asyncio.run_coroutine_threadsafe(self.model.generate(messages), self.loop).result()
            else:
                import anyio.from_thread

                output = anyio.from_thread.run(self.model.generate, messages)
        except Exception as error:  # the provider's, after Inspect's retries; or a sample limit
            raise BackendError(one_line(f"inspect model {self.model}: {type(error).__name__}: {error}"),
                               spent=_spent(error)) from error
        return backend_reply(output, started, prompt, self.detail)
