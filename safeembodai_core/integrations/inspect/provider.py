"""The framework's offline backends as an Inspect model provider: ``--model safeembodai/mock``.

``safeembodai/<name>`` builds the registered LLM backend ``<name>`` (``mock``, the simulated
pilot; ``scripted``; ``litellm``; a plugin's own) with the ``-M key=value`` model arguments as its
options, validated by the backend's options model exactly as a scenario's ``backend.options`` are.
``safeembodai/<name>/<model>`` sets the backend's ``model`` option too (``safeembodai/litellm/openai/gpt-4o``):
Inspect keeps ``-M model=...`` for itself.

A call made by :class:`~.bridge.InspectBackend` carries the prompt's sections, modality names
and the state of the generator the loop drew for that call (the user message's metadata), so
the pilot answers exactly what it answers under ``safeembodai ablate``: same prompt, same dice,
same per-cell MOER for the same seed. A message from anything else (a plain Inspect task) is
read as text and images with no sections, and the dice are seeded from its text.

The backend's whole reply crosses Inspect: its reasoning as a ``ContentReasoning`` part, its
finish reason as Inspect's stop reason (:func:`stop_reason`), chosen so the solver's reading
(:func:`.bridge.backend_reply`, then :func:`~safeembodai_core.models.read_reply`) refuses what the
loop refuses under ``ablate``: a reason Inspect has no name for (``"error"``, ``"stop\\u200b"``)
becomes ``content_filter``, never ``stop``; no reason is ``unknown`` marked as not reported.
"""

from __future__ import annotations

import hashlib
from dataclasses import replace
from typing import Any

import anyio.to_thread
import numpy as np
from inspect_ai.model import (
    ChatMessage, ContentReasoning, ContentText, GenerateConfig, ModelAPI, ModelOutput, ModelUsage, StopDetails,
)

from ...contracts.components import BackendReply
from ...errors import SafeEmbodAIError
from ...models import TokenUsage
from ...models.reply import (
    NORMAL_FINISH_REASONS, as_reply, envelope_error_text, finish_reason_text, normal_finish_reason,
)
from ...trust.quoting import quote_untrusted
from .bridge import META, NOT_REPORTED, REFUSED_REPLY, prompt_from_messages

#: The backend's finish reasons (normalised: :func:`~safeembodai_core.models.reply.normal_finish_reason`)
#: that Inspect has a stop reason for. A normal end is ``stop``; not reported is ``unknown`` with
#: ``stop_details`` of type ``not_reported`` (a plain ``unknown`` is refused by the solver).
_STOP = {"length": "max_tokens", "max_tokens": "max_tokens", "model_length": "model_length",
         "content_filter": "content_filter", "tool_calls": "tool_calls"}
#: Inspect's stop reason for any other abnormal finish reason (``"error"``, ``"stop\u200b"``, ...):
#: Inspect has no "other", and ``unknown`` is what "not reported" crosses as, so the nearest refused
#: one -- "the provider stopped it before a normal end". The reason as the backend sent it rides along
#: in the choice's ``stop_details`` (``type`` ``finish_reason``).
ABNORMAL_STOP = "content_filter"
#: The most choices a reply of several crosses with (the count is what is refused; more adds nothing).
MAX_CHOICES = 1024


def stop_reason(reply: BackendReply) -> tuple[str, StopDetails | None]:
    """The Inspect stop reason (and details) of a backend's reply, chosen so that a reply
    :func:`~safeembodai_core.models.read_reply` refuses is refused again after the round trip
    through Inspect (:func:`.bridge.backend_reply`), and one it accepts is accepted.

    A normal end (``stop``, ``STOP``, ``end_turn``, ...: :func:`normal_finish_reason` in
    :data:`NORMAL_FINISH_REASONS`) is ``stop``; no reason is ``unknown``; ``length``,
    ``content_filter``, ``tool_calls`` are Inspect's own; any other reason (``" STOP "``,
    ``"error"``), and a reply refused as a whole (``envelope_error``), is :data:`ABNORMAL_STOP` with
    what it was in ``stop_details`` (the bridge reads it back). A reply of several choices crosses as
    that many choices (:data:`MAX_CHOICES` at most).
    """
    if reply.envelope_error:
        # as one line of terminal-safe text, clipped visibly: the bridge hands it back as the envelope error
        return ABNORMAL_STOP, StopDetails(type=REFUSED_REPLY, explanation=envelope_error_text(reply.envelope_error))
    normal = normal_finish_reason(reply.finish_reason)
    if normal is None:  # "unknown" alone would read back as refused: say it was not reported
        return "unknown", StopDetails(type=NOT_REPORTED, explanation="the backend reports no finish reason")
    if normal in NORMAL_FINISH_REASONS:
        return "stop", None
    # the reason as sent rides along (the bridge reads it back: refused in the loop's own words)
    sent = StopDetails(type="finish_reason", explanation=quote_untrusted(finish_reason_text(reply.finish_reason), 100))
    return _STOP.get(normal, ABNORMAL_STOP), sent


class SafeEmbodAIModelAPI(ModelAPI):
    """Answers with a registered SafeEmbodAI backend (``model_name`` is its name)."""

    def __init__(self, model_name: str, base_url: str | None = None, api_key: str | None = None,
                 config: GenerateConfig = GenerateConfig(), **model_args: Any) -> None:
        super().__init__(model_name=model_name, base_url=base_url, api_key=api_key, config=config)
        from ...plugin.manager import load_plugins
        from ...plugin.refs import ComponentRef

        backend, _, model = model_name.partition("/")
        options = dict(model_args)
        if model:  # safeembodai/litellm/openai/gpt-4o: Inspect's -M cannot pass "model" (its own argument)
            options["model"] = model
        try:
            self.backend = load_plugins().registry.build_ref(
                "llm_backend", ComponentRef(use=backend, options=options, label="inspect"))
        except SafeEmbodAIError as error:
            raise ValueError(f"safeembodai/{model_name}: {error}") from None

    def max_connections(self) -> int:
        return 8  # it computes locally: more would only queue on the shared cores

    async def generate(self, input: list[ChatMessage], tools: list[Any], tool_choice: Any,
                       config: GenerateConfig) -> ModelOutput:
        prompt, rng = prompt_from_messages(input)
        if rng is None:
            digest = hashlib.blake2b((prompt.system + prompt.user_text).encode(), digest_size=8).digest()
            rng = np.random.default_rng(int.from_bytes(digest, "big"))
        reply = as_reply(await anyio.to_thread.run_sync(self.backend.complete, prompt, rng))
        if not isinstance(reply.text, str) or not isinstance(reply.reasoning, (str, type(None))):
            # what the loop refuses as "not text" crosses as a refused reply, never as a crash here
            what = "text" if not isinstance(reply.text, str) else "reasoning"
            reply = replace(reply, text=reply.text if isinstance(reply.text, str) else "", reasoning=None,
                            envelope_error=f"the backend's reply {what} is not text")
        reason, details = stop_reason(reply)
        content: str | list[Any] = reply.text
        if reply.reasoning:  # the reply's reasoning goes on with it, read for a second plan at the other end
            content = [ContentReasoning(reasoning=reply.reasoning), ContentText(text=reply.text)]
        output = ModelOutput.from_content(self.model_name, content, stop_reason=reason,  # type: ignore[arg-type]
                                          stop_details=details)
        count = reply.choices
        if not reply.envelope_error and isinstance(count, int) and count != 1:  # read_reply refuses it as it is
            output.choices = output.choices[:1] * min(max(count, 0), MAX_CHOICES)
        usage = reply.usage if isinstance(reply.usage, TokenUsage) else TokenUsage()
        output.usage = ModelUsage(input_tokens=usage.prompt_tokens, output_tokens=usage.completion_tokens,
                                  total_tokens=usage.prompt_tokens + usage.completion_tokens)
        if usage.estimated:  # Inspect's usage cannot say so: the output's metadata does (read by the bridge)
            output.metadata = {**(output.metadata or {}), META: {"usage_estimated": True}}
        return output

    def close(self) -> None:
        self.backend.close()
