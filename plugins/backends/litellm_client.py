"""The litellm backend: one chat completion per attempt, with its own retries on transient errors.

Rate limits (429), server errors (5xx), refused connections and timeouts are retried up to
``max_retries`` times with exponential backoff (jitter from the call's seeded rng; a server's
``Retry-After`` is honoured up to ``backoff_max_s``). Anything else -- a bad key, an unknown
model, a request the provider refuses -- fails at once. Either way the failure becomes a
:class:`~safeembodai_core.errors.BackendError` whose message says what went wrong and never
contains the API key. litellm's own retry layers are off (``max_retries=0`` to the openai SDK,
no ``num_retries``) so the count is exactly what the options say.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import structlog

from safeembodai_core.components import BackendReply, LLMBackend
from safeembodai_core.errors import BackendError
from safeembodai_core.logs import redact
from safeembodai_core.models import Prompt, TokenUsage

from .litellm_runtime import import_litellm
from .messages import chat_messages, response_format

log = structlog.get_logger(__name__)

_MESSAGE_CHARS = 300


class _Secret:
    """Holds a credential; its repr and str never show it."""

    __slots__ = ("_value",)

    def __init__(self, value: str | None) -> None:
        self._value = value

    def reveal(self) -> str | None:
        return self._value

    def __repr__(self) -> str:
        return "<secret>" if self._value else "<none>"

    __str__ = __repr__


@dataclass(frozen=True)
class Failure:
    """A classified call failure: what kind, whether retrying can help, and the server's hint."""

    kind: str
    retryable: bool
    detail: str
    retry_after_s: float | None = None


def _retry_after(error: Exception) -> float | None:
    """The server's ``Retry-After`` in seconds (litellm keeps the real headers apart)."""
    for headers in (getattr(error, "litellm_response_headers", None),
                    getattr(getattr(error, "response", None), "headers", None)):
        try:
            if headers and headers.get("retry-after") is not None:
                return max(0.0, float(headers.get("retry-after")))
        except (TypeError, ValueError, AttributeError):
            continue
    return None


_NOT_RETRIED = {
    401: "authentication failed (HTTP 401), check the key in the variable named by api_key_env",
    403: "permission denied (HTTP 403)",
    404: "not found (HTTP 404), check the model name and api_base",
}


def classify(error: Exception) -> tuple[str, bool]:
    """(kind, retryable) for an exception raised by ``litellm.completion``.

    litellm maps most provider errors onto openai's exception classes but not all (a 403 can
    arrive as a plain ``APIError``), so the HTTP status decides wherever there is one.
    """
    import openai

    status = getattr(error, "status_code", None)
    if isinstance(error, openai.AuthenticationError):
        status = 401
    if isinstance(error, openai.APITimeoutError):
        return "timed out", True
    if isinstance(error, openai.RateLimitError) or status == 429:
        return "rate limited (HTTP 429)", True
    if status in _NOT_RETRIED:
        return _NOT_RETRIED[status], False
    if isinstance(error, (openai.BadRequestError, openai.UnprocessableEntityError)) or status in (400, 422):
        return f"request refused (HTTP {status or 400}), check the model name and options", False
    if isinstance(error, openai.APIConnectionError) or "Connection error" in str(error):
        # litellm reports a refused connection as an InternalServerError (HTTP 500)
        return "could not connect (refused or reset)", True
    if isinstance(status, int) and status >= 500:
        return f"server error (HTTP {status})", True
    if isinstance(status, int):
        return f"request failed (HTTP {status})", False
    if isinstance(error, openai.OpenAIError):
        return "provider error", False
    return f"unexpected {type(error).__name__}", False


class LiteLLMBackend(LLMBackend):
    """Sends each prompt through ``litellm.completion``; see :mod:`.litellm_api` for the options."""

    def __init__(self, name: str, options: Any, api_key: str | None,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.name = name
        self.options = options
        self._key = _Secret(api_key)
        self._sleep = sleep
        self._litellm = import_litellm()

    def _scrub(self, text: str) -> str:
        key = self._key.reveal()
        if key:
            text = text.replace(key, "***")
        text = redact(text)
        return text if len(text) <= _MESSAGE_CHARS else text[:_MESSAGE_CHARS] + "..."

    def request(self, prompt: Prompt, rng: np.random.Generator | None = None) -> dict[str, Any]:
        """The keyword arguments of ``litellm.completion`` for ``prompt``, without the key."""
        o = self.options
        kwargs: dict[str, Any] = {
            "model": o.model,
            "messages": chat_messages(prompt, detail=o.image_detail, send_images=o.send_images,
                                      fold_system=o.fold_system_prompt),
            "timeout": o.timeout_s,
            "max_retries": 0,
            "max_tokens": o.max_tokens,
            "drop_params": o.drop_params,
        }
        if o.api_base:
            kwargs["api_base"] = o.api_base
        if o.temperature is not None:
            kwargs["temperature"] = o.temperature
        fmt = response_format(o.json_mode)
        if fmt is not None:
            kwargs["response_format"] = fmt
        if o.send_seed and rng is not None:
            kwargs["seed"] = int(rng.integers(0, 2**31 - 1))
        kwargs.update(o.completion_kwargs)
        return kwargs

    def complete(self, prompt: Prompt, rng: np.random.Generator) -> BackendReply:
        o = self.options
        kwargs = self.request(prompt, rng)
        key = self._key.reveal()
        if key is not None:
            kwargs["api_key"] = key
        for attempt in range(o.max_retries + 1):
            started = time.perf_counter()
            try:
                response = self._litellm.completion(**kwargs)
            except Exception as error:  # every provider error is classified below
                kind, retryable = classify(error)
                failure = Failure(kind, retryable, self._scrub(str(error)), _retry_after(error))
            else:
                return self._reply(response, time.perf_counter() - started)
            if not failure.retryable or attempt == o.max_retries:
                tries = f"{attempt + 1} {'try' if attempt == 0 else 'tries'}"
                log.warning("backend.failed", backend=self.name, model=o.model, reason=failure.kind, tries=attempt + 1)
                raise BackendError(f"llm backend {self.name!r} (model {o.model}) gave up after {tries}: "
                                   f"{failure.kind}; provider said: {failure.detail}") from None
            delay = min(o.backoff_max_s, o.backoff_s * 2**attempt) * (0.5 + float(rng.random()))
            if failure.retry_after_s is not None:
                delay = min(o.backoff_max_s, max(delay, failure.retry_after_s))
            log.info("backend.retry", backend=self.name, model=o.model, reason=failure.kind,
                     attempt=attempt + 1, delay_s=round(delay, 3))
            self._sleep(delay)
        raise AssertionError("unreachable")  # pragma: no cover

    def _reply(self, response: Any, latency: float) -> BackendReply:
        choices = getattr(response, "choices", None) or []
        text = ""
        if choices:
            message = getattr(choices[0], "message", None)
            text = getattr(message, "content", None) or ""
            if getattr(choices[0], "finish_reason", None) == "length":
                log.info("backend.truncated", backend=self.name, model=self.options.model, chars=len(text))
        usage = getattr(response, "usage", None)
        tokens = TokenUsage(
            prompt_tokens=max(0, int(getattr(usage, "prompt_tokens", 0) or 0)),
            completion_tokens=max(0, int(getattr(usage, "completion_tokens", 0) or 0)),
        )
        model = str(getattr(response, "model", None) or self.options.model)
        return BackendReply(text=str(text), usage=tokens, latency_s=latency, model=model)
