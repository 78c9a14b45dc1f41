"""A completion read into a :class:`BackendReply`: from the server's own bytes where we have them.

Two routes, decided once per backend (:func:`.client.strict_route`):

* **The strict raw reading** -- every model litellm sends through the openai SDK (provider
  ``openai``: ``gpt-4o``, ``openai/<name>``; the ``gpt-4o`` and ``local`` backends, and
  ``litellm`` with such a model). The body the server sent, as recorded by the backend's own
  transport (:mod:`.litellm_transport`), is read by the core's strict reader
  (:func:`safeembodai_core.models.chat_completion.reply_from_chat_completion`), not litellm's
  parsed object, which moves a leading ``<think>`` block of the content into
  ``reasoning_content``, keeps the last of duplicate keys and takes choice 0 whatever its index:
  :func:`reply_from_body`. The content stays whole (the core splits the reasoning off and reads
  it for a second plan), the reasoning the server sent apart (``reasoning_content``) comes along,
  every choice is counted, the finish reason is passed on as sent (clipped at 64 characters; the
  core normalises it), and the reply's origin (``scheme://host:port``) is recorded.
* **litellm's object** -- any other provider (``anthropic/...``, ``azure/...``, ...; reached
  with a key): :func:`reply_from_response`. The text is the first choice's content, ``choices``
  how many litellm holds, the reasoning litellm's ``reasoning_content``, and the finish reason
  litellm's -- except that litellm maps any reason it does not know (and some it does, such as
  Cohere's ``ERROR``) to ``"stop"``: where litellm says ``"stop"``, the provider's own reason
  (``native_finish_reason``) is reported instead unless it is one that means a normal end. The
  origin is not known there (None).

Either way the backend's own secrets are masked from the text and the reasoning (a server that
reflects the key), token counts are whole numbers clamped to [0, 2**31 - 1], and the model name
is a short plain token (the configured one when the server names none).
"""

from __future__ import annotations

from typing import Any, Iterable

from safeembodai_core.contracts.components import BackendReply
from safeembodai_core.logs import mask_values
from safeembodai_core.models import TokenUsage
from safeembodai_core.models.chat_completion import read_usage, reply_from_chat_completion, said_usage
from safeembodai_core.models.reply import (NORMAL_FINISH_REASONS, finish_reason_text, normal_finish_reason,
                                           plain_token)

def token_usage(usage: Any) -> TokenUsage | None:
    """litellm's usage object through the one strict reading (None: unusable, to be counted)."""
    return read_usage(usage)


def model_name(reported: Any, configured: str, secrets: Iterable[str]) -> str:
    """The model the server names (a short plain token, secrets masked), or the configured one."""
    if not isinstance(reported, str) or not reported:
        return configured
    return plain_token(mask_values(reported, secrets))


def _masked(text: str | None, secrets: Iterable[str]) -> str | None:
    return mask_values(text, secrets) if isinstance(text, str) else text


def reply_from_body(body: bytes, origin: str | None, configured: str, secrets: Iterable[str],
                    latency_s: float) -> BackendReply:
    """The strict raw reading of a chat-completion body (see the module docstring)."""
    secrets = tuple(secrets)
    reply = reply_from_chat_completion(body, origin=origin)
    reply.text = mask_values(reply.text, secrets)
    reply.reasoning = _masked(reply.reasoning, secrets)
    reply.envelope_error = _masked(reply.envelope_error, secrets)
    # masked before it is clipped: a cut must never leave part of a reflected key readable
    reply.finish_reason = finish_reason_text(_masked(reply.finish_reason, secrets))
    reply.model = model_name(reply.model, configured, secrets)
    reply.latency_s = latency_s
    return reply


def finish_reason(choice: Any) -> str | None:
    """litellm's finish reason of ``choice``, or the provider's own where litellm says stop (module docstring)."""
    mapped = getattr(choice, "finish_reason", None)
    fields = getattr(choice, "provider_specific_fields", None)
    native = fields.get("native_finish_reason") if isinstance(fields, dict) else None
    if mapped == "stop" and native is not None and normal_finish_reason(native) not in NORMAL_FINISH_REASONS:
        return finish_reason_text(native)
    return finish_reason_text(mapped)


def _choices(response: Any) -> list[Any]:
    try:
        choices = getattr(response, "choices", None)
        return list(choices) if isinstance(choices, (list, tuple)) else []
    except Exception:  # a response object that misbehaves is a response without choices
        return []


def reply_from_response(response: Any, configured: str, secrets: Iterable[str], latency_s: float) -> BackendReply:
    """litellm's parsed response read into a reply (routes not read raw; see the module docstring)."""
    secrets = tuple(secrets)
    choices = _choices(response)
    choice = choices[0] if choices else None
    message = getattr(choice, "message", None)
    content = getattr(message, "content", None)
    reasoning = getattr(message, "reasoning_content", None)
    said = getattr(response, "usage", None)
    usage = token_usage(said)
    return BackendReply(
        text=mask_values(content if isinstance(content, str) else "", secrets),
        usage=usage or said_usage(said), usage_known=usage is not None, latency_s=latency_s,
        model=model_name(getattr(response, "model", None), configured, secrets),
        finish_reason=finish_reason(choice) if choice is not None else None,
        reasoning=mask_values(reasoning, secrets) if isinstance(reasoning, str) and reasoning else None,
        choices=len(choices), origin=None)
