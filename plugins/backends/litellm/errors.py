"""What went wrong with a litellm call: a short kind, whether a retry can help, and a clean message.

litellm maps most provider errors onto openai's exception classes but not all (a 403 can arrive
as a plain ``APIError``), so the HTTP status decides wherever there is one. A reply that came
back 200 but is not a chat completion (``{"choices": "x"}``, missing fields, not JSON at all)
is raised by litellm as an ``InternalServerError`` with status 500 although no server said 500;
it is told apart by the absence of any real HTTP response behind the error and reported as a
malformed reply.

On the routes whose exchanges the backend's own transport records (:mod:`.litellm_transport`)
the record decides first (:func:`exchange_failure`), since it holds what the server really sent:

* a 3xx -- the server tried to send the call elsewhere: ``redirected`` with the status and the
  Location's origin, never followed and not retried (a request the transport refused to send,
  to another origin or after a redirect, likewise);
* an HTTP 200 whose body is only an error object (``{"error": {"message": ...}}``, no
  ``choices``) -- the provider's error, its message quoted, retried like a server error (5xx);
  litellm itself reports it as some 4xx "(no message)";
* any other 200 that litellm could not read -- a malformed reply (retried once);
* a body longer than the transport reads -- a malformed reply too.

A request that carried image parts and came back refused (HTTP 400/422/500, or an error object in
an HTTP 200) with words that say the model takes no images -- llama-cpp-python serving a text-only
model fails in its chat template with "can only concatenate str (not list) to str";
``llama-server``, vLLM, Ollama and LM Studio say "image input is not supported", "not a multimodal
model", ... -- is reported plainly as :data:`TEXT_ONLY` and not retried (:func:`images_refused`).

Every text a provider (or litellm, about a provider) wrote passes through :func:`scrub_message`
before it reaches a :class:`~safeembodai_core.errors.BackendError` or a log: one line, no
traceback, no file path, no class repr, no control character, no secret, at most 300 characters.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, replace
from typing import Any, Iterable

from safeembodai_core.logs import mask_values, redact
from safeembodai_core.models.chat_completion import error_text
from safeembodai_core.trust.text import CONTROL_OR_LAYOUT

from .call import CallTimedOut, TooManyHungCalls

MESSAGE_CHARS = 300
MALFORMED = "malformed reply (not a chat completion)"
TOO_LARGE = "malformed reply (body too large to read)"
TIMED_OUT = "timed out"
SERVER_ERROR = "server error"
ERROR_IN_200 = "provider error in an HTTP 200 reply"
RATE_LIMITED = "rate limited (HTTP 429)"
TEXT_ONLY = ("this model does not take images (the server failed on the request's image parts); give it the "
             "text-only perception: set `perception: text` in the scenario (docs/backends.md, "
             "\"Perception for text-only models\")")

_NOT_RETRIED = {
    401: "authentication failed (HTTP 401), check the key in the variable named by api_key_env",
    403: "permission denied (HTTP 403)",
    404: "not found (HTTP 404), check the model name and api_base",
}
_IMAGE_STATUSES = (400, 422, 500)
_IMAGES_REFUSED = re.compile(
    r"can only concatenate str \(not \W?list\W?\) to str"  # llama-cpp-python: a chat template on a parts list
    r"|\b(?:image|images|vision|multi-?modal)\b[^.;]{0,80}?\b(?:not supported|unsupported|not enabled|not available)"
    r"|\b(?:does not|doesn't|do not|cannot|can't)\s+(?:support|accept|take|handle)\s+(?:image|vision|multi-?modal)"
    r"|\bnot an? (?:multi-?modal|vision) model"
    r"|\bimage_url is only supported",
    re.I)
_TRACEBACK = re.compile(r"Traceback \(most recent call last\).*", re.S)
_FILE_LINE = re.compile(r"File \"[^\"]*\", line \d+(, in \S+)?")
_PATH = re.compile(r"(?:[A-Za-z]:)?(?:[\\/][\w.\-+@~]+){2,}[\\/]?(?::\d+)?")
_REPR = re.compile(r"<[^<>]{0,200}>")
_LIBRARY_PREFIX = re.compile(r"^(?:\s*(?:litellm\.)?\w+(?:Error|Exception)(?::| -)\s*)+")


@dataclass(frozen=True)
class Failure:
    """A classified call failure: what kind, whether retrying can help, and the server's hint."""

    kind: str
    retryable: bool
    detail: str
    retry_after_s: float | None = None


def retry_after(error: Exception) -> float | None:
    """The server's ``Retry-After`` in seconds (litellm keeps the real headers apart)."""
    for headers in (getattr(error, "litellm_response_headers", None),
                    getattr(getattr(error, "response", None), "headers", None)):
        try:
            if headers and headers.get("retry-after") is not None:
                return min(86_400.0, max(0.0, float(headers.get("retry-after"))))
        except (TypeError, ValueError, AttributeError):
            continue
    return None


def _chain(error: BaseException) -> Iterable[BaseException]:
    seen: set[int] = set()
    link: BaseException | None = error
    while link is not None and id(link) not in seen and len(seen) < 16:
        seen.add(id(link))
        yield link
        link = link.__cause__ or link.__context__


def _answered_with_an_error_status(error: Exception) -> bool:
    """Whether a real HTTP error response stands behind ``error`` (not one litellm made up)."""
    import httpx
    import openai

    if getattr(error, "litellm_response_headers", None) is not None:
        return True
    for link in _chain(error):
        if isinstance(link, httpx.HTTPStatusError):
            return True
        if isinstance(link, openai.APIStatusError) and not type(link).__module__.startswith("litellm"):
            return True
    return False


def classify(error: Exception) -> tuple[str, bool]:
    """(kind, retryable) for an exception raised by a call to ``litellm.completion``."""
    import openai

    if isinstance(error, TooManyHungCalls):
        return "too many timed-out calls still open", False
    if isinstance(error, (CallTimedOut, openai.APITimeoutError)):
        return TIMED_OUT, True
    status = getattr(error, "status_code", None)
    if isinstance(error, openai.AuthenticationError):
        status = 401
    if isinstance(error, openai.RateLimitError) or status == 429:
        return RATE_LIMITED, True
    if status in _NOT_RETRIED:
        return _NOT_RETRIED[status], False
    if isinstance(error, (openai.BadRequestError, openai.UnprocessableEntityError)) or status in (400, 422):
        return f"request refused (HTTP {status or 400}), check the model name and options", False
    if isinstance(error, openai.APIConnectionError) or "Connection error" in str(error):
        # litellm reports a refused connection as an InternalServerError (HTTP 500)
        return "could not connect (refused or reset)", True
    if status == 500 and isinstance(error, openai.OpenAIError) and not _answered_with_an_error_status(error):
        return MALFORMED, True  # the caller allows it one retry only
    if isinstance(status, int) and 500 <= status < 600:
        return f"{SERVER_ERROR} (HTTP {status})", True
    if isinstance(status, int):
        return f"request failed (HTTP {status})", False
    if isinstance(error, openai.OpenAIError):
        return "provider error", False
    return f"unexpected {type(error).__name__}", False


def is_malformed(kind: str) -> bool:
    """Whether ``kind`` is a malformed reply (allowed one retry only)."""
    return kind.startswith("malformed reply")


def _error_only_message(body: bytes | None) -> str | None:
    """The message of a body that is only an ``{"error": ...}`` object (no ``choices``); None otherwise."""
    import json

    try:
        data = json.loads(body or b"")
    except (ValueError, RecursionError):
        return None
    if not isinstance(data, dict) or "error" not in data or "choices" in data:
        return None
    return error_text(data) or "(no message)"


def exchange_failure(recorder: Any, secrets: Iterable[str] = ()) -> Failure | None:
    """The failure the transport's record of a call shows (module docstring); None when it shows none."""
    last = recorder.last if recorder is not None else None
    if last is None:
        return None
    redirect = recorder.redirected()
    if redirect is not None:
        target = scrub_message(redirect.location or "no location", secrets)
        return Failure(f"redirected (HTTP {redirect.status}), not followed: an answer is only read from the "
                       "configured server", False, f"Location {target}")
    if last.refused is not None and last.status is None:
        return Failure("request not sent", False, scrub_message(last.refused, secrets))
    if last.refused is not None:
        return Failure(TOO_LARGE, True, scrub_message(last.refused, secrets))
    if last.status is None or not 200 <= last.status < 300 or last.body is None:
        return None  # no answer had (a timeout, a refused connection) or an HTTP error status: classify()
    message = _error_only_message(last.body)
    if message is not None:
        return Failure(ERROR_IN_200, True, scrub_message(message, secrets))
    return Failure(MALFORMED, True, "the server's HTTP 200 body is not a chat completion litellm can read")


def repeated(failure: Failure, previous: Failure | None) -> Failure:
    """``failure``, not retryable when it repeats ``previous`` exactly on the same request.

    A server error (HTTP 5xx, or an error object in an HTTP 200) that comes back with the same
    status and the same text is the server refusing this request, not a passing overload: one
    retry finds that out, more would only burn the backoff. Rate limits (429), timeouts and
    refused connections repeat by nature and keep their retries.
    """
    server_side = failure.kind.startswith(SERVER_ERROR) or failure.kind == ERROR_IN_200
    if (failure.retryable and previous is not None and server_side
            and (failure.kind, failure.detail) == (previous.kind, previous.detail)):
        return replace(failure, kind=f"{failure.kind}, the same twice on the same request (not transient)",
                       retryable=False)
    return failure


def images_refused(failure: Failure, status: int | None, sent_images: bool) -> Failure:
    """``failure`` as :data:`TEXT_ONLY` (not retried) when it is a text-only model refusing images.

    That is: the request carried image parts (``sent_images``), the server answered it with an
    HTTP 400, 422 or 500 (``status``) or an error object in an HTTP 200, and its text says the
    model takes no images (module docstring). Any other failure comes back unchanged.
    """
    answered = status in _IMAGE_STATUSES or failure.kind == ERROR_IN_200
    if not sent_images or not answered or is_malformed(failure.kind) or not _IMAGES_REFUSED.search(failure.detail):
        return failure
    return Failure(TEXT_ONLY, False, failure.detail)


def format_hint(failure: Failure, options: Any) -> str:
    """A pointer to ``json_mode`` when the server's refusal names ``response_format``."""
    if "response_format" not in failure.detail:
        return ""
    return (f" (this server does not accept json_mode {options.json_mode!r}: see "
            "docs/local_models.md for the form each server reads)")


def scrub_message(text: str, secrets: Iterable[str] = ()) -> str:
    """``text`` as one clean line: secrets masked, no traceback, path, repr or control character."""
    text = mask_values(text, secrets)
    text = redact(text)
    text = _TRACEBACK.sub(" ", text)
    text = _FILE_LINE.sub(" ", text)
    text = _REPR.sub(" ", text)
    text = _PATH.sub("<path>", text)
    text = CONTROL_OR_LAYOUT.sub(" ", text)
    text = _LIBRARY_PREFIX.sub("", " ".join(text.split()))
    text = text.strip(" ,;:-") or "(no message)"
    return text if len(text) <= MESSAGE_CHARS else text[:MESSAGE_CHARS] + "..."
