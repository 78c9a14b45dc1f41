"""The litellm backend: one chat completion per attempt, with its own retries on transient errors.

Each attempt must complete within ``timeout_s`` as a whole (:mod:`.litellm_call`), not merely
per socket read. Rate limits (429), server errors (5xx), refused connections and timeouts are
retried up to ``max_retries`` times with exponential backoff (jitter from the call's seeded rng;
a server's ``Retry-After`` is honoured up to ``backoff_max_s``); a malformed reply (a 200 that is
not a chat completion) is retried once, since a broken proxy or a restarting server can send one
but a server that always does would only burn the backoff; so is an HTTP error whose status and
text repeat word for word on the same request (a server that refuses the request itself, like
llama-cpp-python answering an unknown ``response_format`` with HTTP 500, is not overloaded). Anything
else -- a bad key, an unknown model, a request the provider refuses, a text-only model refusing the
image parts (said plainly, naming ``perception: text``: :func:`.litellm_errors.images_refused`) --
fails at once. Either way the failure becomes a
:class:`~safeembodai_core.errors.BackendError` with one clean line of the provider's text
(:mod:`.litellm_errors`). litellm's own retry layers are off (``max_retries=0`` to the openai
SDK, no ``num_retries``) so the count is exactly what the options say.

The configured key, and any credential in ``completion_kwargs``, is registered with
:func:`safeembodai_core.logs.register_secret` when the backend is built, so every text that
passes through ``redact`` is masked of it, and it is masked from the answer text before the
reply leaves the backend: a server that reflects the key cannot get it stored or shown.

What is read from the server depends on the route litellm takes (:func:`strict_route`, decided
once per backend). Every model litellm sends through the openai SDK (provider ``openai``:
``gpt-4o``, ``openai/<name>``; the ``gpt-4o`` and ``local`` backends) gets the *strict raw
reading*: litellm is handed the backend's own ``openai.OpenAI`` client, whose transport records
each exchange and follows no redirect (:mod:`.litellm_transport`); the reply is read from the
body the server sent, by the core's strict reader, and failures are classified from that record
first (a 3xx is an error, never followed nor retried; an HTTP 200 carrying only an error object
is the provider's error, retried like a 5xx). Any other provider (``anthropic/...``, ...) is read
from litellm's parsed object (:mod:`.litellm_reply`), without an origin.
"""

from __future__ import annotations

import os
import re
import time
import weakref
from typing import Any, Callable

import numpy as np
import structlog

from safeembodai_core.contracts.components import BackendReply, LLMBackend
from safeembodai_core.errors import BackendError
from safeembodai_core.logs import register_secret
from safeembodai_core.models import Prompt, TokenUsage
from safeembodai_core.models.control import DEFAULT_LIMITS, ControlLimits
from safeembodai_core.models.chat_completion import counted_usage, usage_believable
from safeembodai_core.models.reply import NORMAL_FINISH_REASONS, normal_finish_reason
from safeembodai_core.trust.quoting import quote_untrusted

from .options import NO_KEY
from .call import CallTimedOut, TooManyHungCalls, call_with_deadline
from .errors import (MALFORMED, RATE_LIMITED, Failure, classify, exchange_failure, format_hint, images_refused,
                     is_malformed, repeated, retry_after, scrub_message)
from .limiter import limiter_for
from .preflight import endpoint
from .reply import reply_from_body, reply_from_response
from .runtime import count_completion_tokens, count_prompt_tokens, import_litellm
from .transport import Recorder, openai_client, recording
from ..messages import carries_images, chat_messages, response_format

log = structlog.get_logger(__name__)

_MALFORMED_RETRIES = 1
#: The shortest hold-off after a 429, whatever ``backoff_max_s`` or ``Retry-After`` say.
MIN_RATE_LIMIT_WAIT_S = 0.1
#: A 429 that no waiting cures (OpenAI's ``insufficient_quota``): it fails at once, as a bad key does.
_QUOTA_SPENT = re.compile(r"insufficient_quota|exceeded your current quota|check your plan and billing", re.I)
_SECRET_NAME = re.compile(r"authorization|api[-_]?key|secret|password|passwd|credential|cookie|(^|[-_])token$", re.I)
_MIN_SECRET_CHARS = 4


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


def option_secrets(completion_kwargs: dict[str, Any]) -> list[str]:
    """Credentials inside ``completion_kwargs``: string values under a credential-like name, at any
    depth (``extra_headers: {Authorization: Bearer ...}``, ``aws_secret_access_key``, ...), and the
    token after an ``Authorization`` header's scheme."""
    found: list[str] = []

    def visit(value: Any, named_secret: bool) -> None:
        if isinstance(value, dict):
            for key, item in value.items():
                visit(item, named_secret or bool(isinstance(key, str) and _SECRET_NAME.search(key)))
        elif isinstance(value, (list, tuple)):
            for item in value:
                visit(item, named_secret)
        elif named_secret and isinstance(value, str) and value.strip():
            found.append(value.strip())
            scheme, _, token = value.strip().partition(" ")
            if token.strip() and scheme.isalpha():
                found.append(token.strip())

    visit(completion_kwargs, False)
    return found


def strict_route(options: Any, litellm: Any) -> bool:
    """Whether litellm sends ``options.model`` through the openai SDK's chat completions (provider
    ``openai``, and not a model litellm bridges to the Responses API, which it calls with a client
    of its own: ``gpt-5-pro``, ``o1-pro``, ...)."""
    try:
        model, provider, _, _ = litellm.get_llm_provider(
            model=options.model, api_base=options.api_base,
            custom_llm_provider=options.completion_kwargs.get("custom_llm_provider"))
    except Exception:  # a model id litellm cannot place: its call will say why
        return False
    if provider != "openai":
        return False
    try:
        mode = litellm.get_model_info(model, custom_llm_provider=provider).get("mode")
    except Exception:  # a model litellm has no facts about (openai/<local name>): chat completions
        return True
    return mode in (None, "chat")


class _Client:
    """Holds the backend's own openai client (it holds the key); its repr never shows it."""

    __slots__ = ("value",)

    def __init__(self, value: Any) -> None:
        self.value = value

    def __repr__(self) -> str:
        return "<openai client>"


class LiteLLMBackend(LLMBackend):
    """Sends each prompt through ``litellm.completion``; see :mod:`.options` for the options."""

    def __init__(self, name: str, options: Any, api_key: str | None,
                 sleep: Callable[[float], None] = time.sleep) -> None:
        self.name = name
        self.options = options
        self._key = _Secret(api_key)
        secrets = [api_key] if api_key and api_key != NO_KEY else []
        secrets += [s for s in option_secrets(options.completion_kwargs) if len(s) >= _MIN_SECRET_CHARS]
        for secret in secrets:
            register_secret(secret)
        self._secrets = tuple(secrets)
        self._sleep = sleep
        self._litellm = import_litellm()
        self._limits = DEFAULT_LIMITS
        self._sampling: dict[str, float | int] | None = None
        self._client: _Client | None = None
        self._limiter = limiter_for(options.api_base or "", options.model)
        self.concurrency = options.concurrency
        if strict_route(options, self._litellm):
            self._client = _Client(self._strict_client(api_key))
            # a backend dropped without close() still lets go of its connections
            self._finalizer = weakref.finalize(self, self._client.value.close)

    def _strict_client(self, api_key: str | None) -> Any:
        """The openai client of the strict raw reading (see the module docstring), built once."""
        o = self.options
        if api_key is None:  # what litellm falls back to; masked like a configured key
            api_key = os.environ.get("OPENAI_API_KEY") or NO_KEY
            if api_key != NO_KEY and len(api_key) >= _MIN_SECRET_CHARS:
                register_secret(api_key)
                self._secrets += (api_key,)
                self._key = _Secret(api_key)
        base_url = o.api_base or endpoint(o, self._litellm)
        # None: a model litellm places only through completion_kwargs' custom_llm_provider (httpx then raises)
        return openai_client(base_url, api_key, o.timeout_s)  # type: ignore[arg-type]

    def prepare_attempt(self, index: int, limits: ControlLimits, rng: np.random.Generator) -> dict[str, float | int]:
        """Called by Algorithm 1 before attempt ``index`` of a step (0: the first try).

        The next :meth:`complete` sends a decoding schema built from ``limits`` and this attempt's
        sampling: ``temperature + index * retry_temperature_step`` (capped at 2) and, with
        ``send_seed``, a seed drawn from ``rng`` (seeded by trial, step and attempt). Returns
        what will be sent, for the attempt's record.
        """
        self._limits = limits
        self._sampling = self._draw_sampling(index, rng)
        return dict(self._sampling)

    def _draw_sampling(self, index: int, rng: np.random.Generator | None) -> dict[str, float | int]:
        o = self.options
        sampling: dict[str, float | int] = {}
        if o.temperature is not None:
            sampling["temperature"] = round(min(2.0, o.temperature + index * o.retry_temperature_step), 6)
        if o.send_seed and rng is not None:
            sampling["seed"] = int(rng.integers(0, 2**31 - 1))
        return sampling

    def _scrub(self, text: str) -> str:
        """The one way a provider's or litellm's text reaches an error or a log."""
        return scrub_message(text, self._secrets)

    def cache_request(self, prompt: Prompt) -> dict[str, Any]:
        """:meth:`request` as the response cache keys it: what is sent, the prepared attempt kept,
        without the timeout (it does not change the answer)."""
        kwargs = self.request(prompt, consume=False)
        kwargs.pop("timeout", None)
        return kwargs

    def request(self, prompt: Prompt, rng: np.random.Generator | None = None, consume: bool = True) -> dict[str, Any]:
        """The keyword arguments of ``litellm.completion`` for ``prompt``, without the key;
        ``consume`` uses up the attempt :meth:`prepare_attempt` prepared."""
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
        sampling = self._sampling
        if consume:
            self._sampling = None  # prepared for one call only
        kwargs.update(sampling if sampling is not None else self._draw_sampling(0, rng))
        fmt = response_format(o.json_mode, self._limits, o.max_tokens)
        if fmt is not None:
            kwargs["response_format"] = fmt
        kwargs.update(o.completion_kwargs)
        return kwargs

    def complete(self, prompt: Prompt, rng: np.random.Generator) -> BackendReply:
        kwargs = self.request(prompt, rng)
        key = self._key.reveal()
        if key is not None:
            kwargs["api_key"] = key
        if self._client is not None:
            kwargs["client"] = self._client.value
        try:
            return self._call(kwargs, rng)
        finally:  # a give-up or an interrupt while the probe: the next waiting call goes, alone (no-op otherwise)
            self._limiter.settle(answered=False)

    def _call(self, kwargs: dict[str, Any], rng: np.random.Generator) -> BackendReply:
        """Ask until answered or given up (:meth:`_ask`). What the tries before the answer were paid
        (:meth:`_paid`) is added to the reply's usage; a give-up carries it as ``BackendError.spent``."""
        paid: list[TokenUsage] = []
        try:
            reply = self._ask(kwargs, rng, paid)
        except BackendError as error:
            error.spent = sum(paid, TokenUsage()) if paid else None
            raise
        if paid:
            reply.usage = sum(paid, reply.usage)
        return reply

    def _paid(self, error: Exception, recorder: Recorder, kwargs: dict[str, Any]) -> TokenUsage | None:
        """What a failed try was paid, counted here (estimated), or None when it was not paid: a whole
        HTTP 200 body the strict reading refused (the server answered: the request and the body's
        length), a call abandoned at its deadline (the server may have answered after: the request
        and ``max_tokens``, the most it can be). A 429, a 4xx/5xx or a refused connection is not billed."""
        last = recorder.last if recorder is not None else None
        if last is not None and last.status == 200 and last.body is not None:
            answer = last.body.decode("utf-8", "replace")
        elif isinstance(error, CallTimedOut):
            answer = None
        else:
            return None
        usage = self._counted(kwargs["messages"], answer if answer is not None else "")
        if answer is None:
            usage = usage.model_copy(update={"completion_tokens": self.options.max_tokens})
        return usage

    def _ask(self, kwargs: dict[str, Any], rng: np.random.Generator, paid: list[TokenUsage]) -> BackendReply:
        """Ask until answered or given up: pacing, 429 hold-offs and retries (:meth:`complete`);
        each failed try that was paid goes on ``paid``."""
        o = self.options
        malformed = attempt = limited = 0
        first_429 = 0.0
        previous: Failure | None = None
        images = carries_images(kwargs["messages"])
        held_since: float | None = None  # when this call first waited behind another call's 429
        while True:
            if held_since is None and not first_429 and self._limiter.recovering:
                held_since = time.monotonic()
            self._pace()
            started = time.perf_counter()
            with recording() as recorder:  # call_with_deadline's worker sees it (a context copy)
                failure = response = cost = None
                try:
                    response = call_with_deadline(self._litellm.completion, kwargs, o.timeout_s)
                except (CallTimedOut, TooManyHungCalls) as error:
                    failure = self._failure(error, recorder, images)
                    cost = self._paid(error, recorder, kwargs)
                except Exception as error:  # every provider error is classified below
                    # litellm could not parse a whole HTTP 200 body that the strict reading takes (a usage
                    # it will not take, say): that reading is the reply, and the call is not paid again
                    if not self._answered(recorder):
                        failure = self._failure(error, recorder, images)
                        cost = self._paid(error, recorder, kwargs)
                if failure is None:
                    reply = self._reply(response, recorder, time.perf_counter() - started)
                    if not (reply.usage_known and usage_believable(reply.usage, reply.text)):
                        # the call was paid all the same: never counted as 0
                        reply.usage = counted_usage(reply.usage, self._counted(kwargs["messages"],
                                                                               reply.text + (reply.reasoning or "")))
                    self._limiter.spent(reply.usage.total, o.tokens_per_minute)
                    self._limiter.settle(answered=True)  # calls held after a 429 may go, its tokens counted
                    return reply
            if cost is not None:
                paid.append(cost)
            if failure.kind == RATE_LIMITED and _QUOTA_SPENT.search(failure.detail):
                failure = Failure(f"{RATE_LIMITED}: the account's quota is spent", False, failure.detail)
            elif failure.kind == RATE_LIMITED:  # not a retry: the run slows down until the provider lets it on
                # refused since its own first 429, or since it first waited behind another call's
                first_429 = first_429 or held_since or time.monotonic()
                try:
                    self._rate_limited(failure, limited, first_429, rng)
                finally:
                    self._limiter.settle(answered=False)  # held again: the next call to go is the next probe
                limited += 1
                continue
            self._limiter.settle(answered=True)  # any other failure: not the provider's limit
            if is_malformed(failure.kind):
                malformed += 1
                failure = Failure(failure.kind, malformed <= _MALFORMED_RETRIES, failure.detail, failure.retry_after_s)
            failure, previous = repeated(failure, previous), failure
            if not failure.retryable or attempt == o.max_retries:
                tries = f"{attempt + 1} {'try' if attempt == 0 else 'tries'}"
                log.warning("backend.failed", backend=self.name, model=o.model, reason=failure.kind, tries=attempt + 1)
                raise BackendError(f"llm backend {self.name!r} (model {o.model}) gave up after {tries}: "
                                   f"{failure.kind}; provider said: {failure.detail}"
                                   f"{format_hint(failure, o)}") from None
            delay = min(o.backoff_max_s, o.backoff_s * 2**attempt) * (0.5 + float(rng.random()))
            if failure.retry_after_s is not None:
                delay = min(o.backoff_max_s, max(delay, failure.retry_after_s))
            log.info("backend.retry", backend=self.name, model=o.model, reason=failure.kind,
                     attempt=attempt + 1, delay_s=round(delay, 3))
            attempt += 1
            self._sleep(delay)

    def _pace(self) -> None:
        """Wait for this model's turn (:mod:`.limiter`): its pace and any 429 hold-off."""
        wait = self._limiter.reserve(self.options.requests_per_minute)
        if wait > 0:
            self._sleep(wait)

    def _rate_limited(self, failure: Failure, limited: int, since: float, rng: np.random.Generator) -> None:
        """A 429: every call to this model now holds back for the server's ``Retry-After``, else a
        doubling backoff -- at most ``backoff_max_s``, at least :data:`MIN_RATE_LIMIT_WAIT_S` (a 429
        always means wait); a call still refused ``rate_limit_wait_s`` after its first 429 (or after it
        first waited behind another call's 429) gives up
        with a :class:`BackendError`."""
        o = self.options
        if failure.retry_after_s is not None:
            delay = min(o.backoff_max_s, failure.retry_after_s)
        else:
            delay = min(o.backoff_max_s, max(o.backoff_s, 0.25) * 2**min(limited, 16)) * (0.5 + float(rng.random()))
        delay = max(MIN_RATE_LIMIT_WAIT_S, delay)
        waited = time.monotonic() - since
        if waited + delay > o.rate_limit_wait_s:
            log.warning("backend.failed", backend=self.name, model=o.model, reason=failure.kind,
                        waited_s=round(waited, 1))
            raise BackendError(f"llm backend {self.name!r} (model {o.model}) gave up: still {failure.kind} after "
                               f"{limited + 1} answers and {waited:.0f} s (rate_limit_wait_s "
                               f"{o.rate_limit_wait_s:g}); provider said: {failure.detail}") from None
        log.info("backend.rate_limited", backend=self.name, model=o.model, times=limited + 1, delay_s=round(delay, 3),
                 retry_after_s=failure.retry_after_s, waited_s=round(waited, 1))
        self._limiter.hold(delay)

    def _failure(self, error: Exception, recorder: Recorder, images: bool) -> Failure:
        """What went wrong: from the transport's record when it shows it, else from the exception;
        a text-only model refusing the request's ``images`` is said plainly (:func:`images_refused`)."""
        last = recorder.last if recorder is not None else None
        status = last.status if last is not None and last.status is not None else getattr(error, "status_code", None)
        if not isinstance(error, (CallTimedOut, TooManyHungCalls)):
            found = exchange_failure(recorder, self._secrets)
            if found is not None and found.kind == MALFORMED:  # litellm's words say what it could not read
                return Failure(MALFORMED, True, self._scrub(str(error)) or found.detail)
            if found is not None:
                return images_refused(found, status, images)
        kind, retryable = classify(error)
        return images_refused(Failure(kind, retryable, self._scrub(str(error)), retry_after(error)), status, images)

    def cost(self, prompt_tokens: int, completion_tokens: int) -> float | None:
        """litellm's list price of the model (its bundled price table, read offline); None when it has none."""
        try:
            prompt, completion = self._litellm.cost_per_token(model=self.options.model, prompt_tokens=prompt_tokens,
                                                              completion_tokens=completion_tokens)
            total = float(prompt) + float(completion)
        except Exception:  # a model litellm has no price for (a local model, a new name)
            return None
        return total if total >= 0 and total == total else None

    def preflight(self) -> None:
        """Before the first trial: the server accepts a connection (:mod:`.litellm_preflight`)."""
        from .preflight import check_reachable

        check_reachable(self.name, self.options, self._litellm)

    def close(self) -> None:
        if self._client is not None:
            self._finalizer()

    def _answered(self, recorder: Recorder) -> bool:
        """Whether the call's last exchange was a whole HTTP 200 body the strict reading takes as a reply."""
        last = recorder.last
        if self._client is None or last is None or last.status != 200 or last.body is None or last.refused:
            return False
        return reply_from_body(last.body, last.origin, self.options.model, self._secrets, 0.0).envelope_error is None

    def _counted(self, messages: list[dict[str, Any]], text: str) -> TokenUsage:
        """The call's tokens counted here, when the server's usage was missing or unusable: the
        model's tokenizer (litellm's ``token_counter``), else the rough count of 4 characters a token."""
        model = self.options.model
        try:
            prompt, answer = (count_prompt_tokens(messages, model, "litellm"),
                              count_completion_tokens(text, model, "litellm"))
        except Exception:  # a model litellm cannot tokenize: the rough count, still never 0
            prompt, answer = count_prompt_tokens(messages, model, "estimate"), count_completion_tokens(text, model,
                                                                                                      "estimate")
        log.warning("backend.usage_estimated", backend=self.name, model=model, prompt_tokens=prompt,
                    completion_tokens=answer)
        return TokenUsage(prompt_tokens=prompt, completion_tokens=answer, estimated=True)

    def _reply(self, response: Any, recorder: Recorder, latency: float) -> BackendReply:
        o = self.options
        if self._client is None:
            reply = reply_from_response(response, o.model, self._secrets, latency)
        else:
            last = recorder.last
            if last is not None and last.body is not None:
                reply = reply_from_body(last.body, last.origin, o.model, self._secrets, latency)
            else:  # litellm answered without a body on record: nothing is read from it
                reply = BackendReply(text="", latency_s=latency, model=o.model,
                                     origin=last.origin if last is not None else None,
                                     envelope_error="the backend recorded no body for this reply")
        if normal_finish_reason(reply.finish_reason) not in NORMAL_FINISH_REASONS or reply.envelope_error:
            log.info("backend.unusual_reply", backend=self.name, model=o.model,
                     finish_reason=quote_untrusted(reply.finish_reason, 64), choices=reply.choices,
                     envelope_refused=reply.envelope_error is not None, chars=len(reply.text))
        return reply
