"""A litellm response read defensively into the pieces of a :class:`BackendReply`.

Everything in a response came from the server. The answer text is returned as it came (the core
parses it) except that the backend's own secrets are masked; the finish reason, the model name
and the token counts are read so that no value can raise, grow without bound or carry control
characters:

* ``finish_reason`` -- litellm maps providers' reasons onto OpenAI's (``end_turn`` -> ``stop``,
  ``max_tokens`` -> ``length``) but turns any reason it does not know (and some it does, such
  as Cohere's ``ERROR``) into ``"stop"``. Where litellm says ``"stop"``, the provider's own reason
  (litellm's ``native_finish_reason``) is reported instead unless it is one of the few that mean
  a normal end, so a server cannot slip an unknown reason past the
  core as a normal stop. A server that sends no reason at all is a ``"stop"`` (litellm's default).
* token counts -- whole numbers clamped to [0, 2**31 - 1]; anything else that reaches this
  module (a string, a list, ``True``) counts 0. A count litellm itself cannot read (a fraction,
  NaN, 1e300) never gets here: litellm rejects the whole reply, which the backend reports as a
  malformed reply (``litellm_errors``) -- such a server is broken, and its answer is not used.
"""

from __future__ import annotations

import math
import re
from numbers import Real
from typing import Any, Iterable

from safeembodai_core.logs import mask_values
from safeembodai_core.models.response import NORMAL_FINISH_REASONS
from safeembodai_core.models import TokenUsage

MAX_TOKENS_REPORTED = 2**31 - 1
REASON_CHARS = 32
MODEL_CHARS = 100
_NOT_PLAIN = re.compile(r"[^A-Za-z0-9_.:/@+\-]")




def plain(value: Any, most: int) -> str:
    """``value`` as a short single token: characters outside ``[A-Za-z0-9_.:/@+-]`` become ``_``."""
    return _NOT_PLAIN.sub("_", str(value)[:most])


def token_count(value: Any) -> int:
    """A server's token count as a sane int: clamped to [0, 2**31 - 1], non-numbers 0; never raises."""
    if isinstance(value, bool) or not isinstance(value, Real):
        return 0
    if isinstance(value, int):
        return min(MAX_TOKENS_REPORTED, max(0, value))
    try:
        number = float(value)
        if not math.isfinite(number):
            return 0
        return int(min(MAX_TOKENS_REPORTED, max(0, int(value))))
    except (TypeError, ValueError, OverflowError, ArithmeticError):
        return 0


def token_usage(usage: Any) -> TokenUsage:
    return TokenUsage(prompt_tokens=token_count(getattr(usage, "prompt_tokens", 0)),
                      completion_tokens=token_count(getattr(usage, "completion_tokens", 0)))


def finish_reason(choice: Any) -> str | None:
    """The reason the answer ended, as a short plain token (see the module docstring)."""
    mapped = getattr(choice, "finish_reason", None)
    fields = getattr(choice, "provider_specific_fields", None)
    native = fields.get("native_finish_reason") if isinstance(fields, dict) else None
    if mapped == "stop" and native is not None and not (isinstance(native, str) and native.lower() in NORMAL_FINISH_REASONS):
        return plain(native, REASON_CHARS) or "_"
    if mapped is None:
        return None
    return plain(getattr(mapped, "value", mapped), REASON_CHARS) or "_"


def first_choice(response: Any) -> Any:
    try:
        choices = getattr(response, "choices", None)
        return choices[0] if isinstance(choices, (list, tuple)) and choices else None
    except Exception:  # a response object that misbehaves is a response without choices
        return None


def answer_text(choice: Any, secrets: Iterable[str]) -> str:
    content = getattr(getattr(choice, "message", None), "content", None)
    return mask_values(content if isinstance(content, str) else "", secrets)


def model_name(response: Any, configured: str, secrets: Iterable[str]) -> str:
    reported = getattr(response, "model", None)
    if not isinstance(reported, str) or not reported:
        return configured
    return plain(mask_values(reported, secrets), MODEL_CHARS)
