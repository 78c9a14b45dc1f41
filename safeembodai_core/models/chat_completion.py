"""An OpenAI-style chat-completion body, read strictly into a :class:`~.reply.BackendReply`.

The body is the server's, so every byte is hostile until read. The JSON is read with the answer's
strict rules (:mod:`.strict_json`) applied to the *whole* envelope: a duplicate key anywhere (two
``content`` keys in a message, two ``finish_reason`` keys in a choice), NaN or a lone surrogate
anywhere refuses the reply, because the SDK and litellm keep the last of two values and a reviewer
reading the body would see the first. :func:`reply_from_chat_completion` never raises: what it
cannot accept becomes the reply's ``envelope_error`` (the core then refuses the answer, and the
attempt's record keeps the body as its text), and the rest is read as:

* ``choices`` -- counted; more than one is refused by :func:`~.reply.read_reply` (one plan per
  reply; nothing here asks for ``n``); none, or a choice whose ``index`` is not 0, is an envelope
  error.
* ``message.content`` -- text or ``null`` (no answer; anything else is an envelope error, as the
  backends always read it); the reply's reasoning -- ``reasoning_content``, ``reasoning``,
  ``thinking`` (text) and the text of ``reasoning_details`` / ``thinking_blocks`` blocks; ``tool_calls``,
  ``function_call`` or ``refusal`` set -- an envelope error (no tool was offered; a refusal is
  not an answer).
* ``finish_reason`` -- as sent (text; a number as its JSON), None when absent or ``null``; a
  relay's ``native_finish_reason`` (the provider's own) replaces it when that one is not a normal end.
* numbers anywhere in the envelope are read as the answer's are: ``NaN``, literals over 32
  characters or magnitudes above 10^15 (a token count of 1e30) refuse the whole reply -- such a
  server is broken; ``usage`` is read by :func:`read_usage`: anything but two whole, non-negative
  counts is unusable (``usage_known`` False), and the backend counts the call's tokens itself, never
  less than what the server said (:func:`said_usage`, :func:`counted_usage`).
* a body that carries an ``error`` (an HTTP 200 carrying an error, with or without choices) -- an
  envelope error that quotes its message; a backend that sees it first treats it as the provider's
  error instead;
* bytes that are not UTF-8, and a lone surrogate anywhere (a ``\\ud800`` escape in ``id``) -- an
  envelope error. Nesting is bounded by JSON's own recursion limit (the answer inside has its 10 levels).
"""

from __future__ import annotations

import json
import math
from typing import Any

from ..trust.quoting import quote_untrusted
from .records import TokenUsage
from .reply import MAX_RESPONSE_CHARS, BackendReply
from .reply import NORMAL_FINISH_REASONS, normal_finish_reason
from .strict_json import QUOTE_CHARS, ResponseParseError, find_objects

MAX_BODY_BYTES = 4 * 1024 * 1024
MAX_TOKENS_REPORTED = 2**31 - 1
_QUOTE = QUOTE_CHARS
#: Message fields that hold reasoning as text, and those that hold it as a list of blocks whose
#: text is under one of :data:`_BLOCK_TEXT` (OpenRouter's ``reasoning_details``, Anthropic-style
#: ``thinking_blocks``): all of it is the reply's reasoning, read for a second plan.
_REASONING_TEXT = ("reasoning_content", "reasoning", "thinking")
_REASONING_BLOCKS = ("reasoning_details", "thinking_blocks")
_BLOCK_TEXT = ("text", "summary", "thinking", "content")


def _count(value: Any) -> int | None:
    """A whole, non-negative token count (an integral float too), clamped to 2**31 - 1; None otherwise."""
    if isinstance(value, bool):
        return None
    if isinstance(value, float):
        if not (value == value and abs(value) < 2**63 and value.is_integer()):
            return None
        value = int(value)
    if not isinstance(value, int) or value < 0:
        return None
    return min(MAX_TOKENS_REPORTED, value)


def usage_believable(usage: TokenUsage, text: str) -> bool:
    """Whether counts a reader took can be what a paid call used: a request is never 0 tokens, nor an
    answer with text (litellm fills a missing usage with zeros for the routes it parses itself)."""
    return usage.prompt_tokens > 0 and (usage.completion_tokens > 0 or not text)


def read_usage(usage: Any) -> TokenUsage | None:
    """A server's ``usage`` (a mapping, or an object with the attributes), strictly: both
    ``prompt_tokens`` and ``completion_tokens`` whole and non-negative, or None -- missing, null,
    negative, fractional, text, or only ``total_tokens`` is unusable, never 0. The one reading of a
    server's usage, for a raw body and for litellm's parsed response alike."""
    if usage is None:
        return None
    get = usage.get if isinstance(usage, dict) else (lambda name: getattr(usage, name, None))
    try:
        prompt, completion = _count(get("prompt_tokens")), _count(get("completion_tokens"))
    except Exception:  # an object whose attributes misbehave has no usable usage
        return None
    if prompt is None or completion is None:
        return None
    return TokenUsage(prompt_tokens=prompt, completion_tokens=completion)


def said_usage(usage: Any) -> TokenUsage:
    """What an unreadable usage (:func:`read_usage` None) still says, as a floor for the call's count:
    each count that is a finite, non-negative number, rounded up (``900.9`` is 901), else 0; marked
    estimated. A spending cap never counts less than the provider's own figure."""
    get = usage.get if isinstance(usage, dict) else (lambda name: getattr(usage, name, None))

    def floor(name: str) -> int:
        try:
            value = get(name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value >= 0:
                return 0
            return min(MAX_TOKENS_REPORTED, math.ceil(value)) if value < 2**63 else MAX_TOKENS_REPORTED
        except Exception:  # an object whose attributes misbehave says nothing
            return 0

    if usage is None:
        return TokenUsage(estimated=True)
    return TokenUsage(prompt_tokens=floor("prompt_tokens"), completion_tokens=floor("completion_tokens"),
                      estimated=True)


def counted_usage(said: TokenUsage, estimate: TokenUsage) -> TokenUsage:
    """The count of a call whose usage was unreadable: per count the larger of what the server said
    (:func:`said_usage`) and the estimate made here, marked estimated."""
    return TokenUsage(prompt_tokens=max(said.prompt_tokens, estimate.prompt_tokens),
                      completion_tokens=max(said.completion_tokens, estimate.completion_tokens), estimated=True)


def error_text(body: Any) -> str | None:
    """The message of a decoded body that carries an ``error``, as the server wrote it (a message
    that is not text as its JSON; ``(no message)`` when it has none), with or without choices; None
    when ``body`` has no error. Untrusted: quote or scrub it before it is shown."""
    if not isinstance(body, dict) or body.get("error") is None:
        return None
    error = body["error"]
    message = error.get("message") if isinstance(error, dict) else error
    if message is None or message == "":
        return "(no message)"
    return message if isinstance(message, str) else json.dumps(message)


def error_message(body: Any) -> str | None:
    """:func:`error_text`, quoted and short."""
    text = error_text(body)
    return None if text is None else quote_untrusted(text, _QUOTE)


def _content(message: dict[str, Any]) -> str:
    content = message.get("content")
    if content is None or isinstance(content, str):
        return content or ""
    raise ResponseParseError(f"the message's content is not text (got {type(content).__name__})")


def _reasoning(message: dict[str, Any]) -> str | None:
    parts: list[str] = []

    def add(value: Any, key: str) -> None:
        if not isinstance(value, str):
            raise ResponseParseError(f"the message's {key} is not text (got {type(value).__name__})")
        if value and value not in parts:
            parts.append(value)

    for key in _REASONING_TEXT:
        if message.get(key) is not None:
            add(message[key], key)
    for key in _REASONING_BLOCKS:
        blocks = message.get(key)
        if blocks is None:
            continue
        if not isinstance(blocks, list) or not all(isinstance(block, dict) for block in blocks):
            raise ResponseParseError(f"the message's {key} is not a list of blocks")
        for block in blocks:
            for field in _BLOCK_TEXT:
                if block.get(field) is not None:
                    add(block[field], f"{key} {field}")
    return "\n".join(parts) if parts else None


def _finish_reason(value: Any) -> str | None:
    if value is None:
        return None
    return value if isinstance(value, str) else json.dumps(value)


def _choice_finish_reason(choice: dict[str, Any]) -> str | None:
    """The choice's finish reason, or its ``native_finish_reason`` (OpenRouter and other relays say
    what the provider said there) when that one is not a normal end: a relay's ``stop`` over a
    provider's ``length`` is a cut-off answer."""
    reason = _finish_reason(choice.get("finish_reason"))
    native = _finish_reason(choice.get("native_finish_reason"))
    if native is not None and (reason is None or normal_finish_reason(native) not in NORMAL_FINISH_REASONS):
        return native
    return reason


def _check_strings(value: Any) -> None:
    """A lone surrogate anywhere in the envelope (a ``\\ud800`` escape in ``id``, say) refuses it."""
    stack = [value]
    while stack:
        node = stack.pop()
        if isinstance(node, dict):
            stack.extend(node.keys())
            stack.extend(node.values())
        elif isinstance(node, list):
            stack.extend(node)
        elif isinstance(node, str) and any("\ud800" <= char <= "\udfff" for char in node):
            raise ResponseParseError("the reply holds a lone surrogate (not valid Unicode)")


def _read(data: Any, reply: BackendReply) -> BackendReply:
    if not isinstance(data, dict):
        raise ResponseParseError(f"the reply is not a JSON object (got {type(data).__name__})")
    usage = read_usage(data.get("usage"))
    # unreadable: what it said is kept as a floor for the count the backend makes (counted_usage)
    reply.usage, reply.usage_known = (usage, True) if usage is not None else (said_usage(data.get("usage")), False)
    if isinstance(data.get("model"), str):
        reply.model = data["model"]  # whole: a backend masks its secrets before it shortens it
    message = error_message(data)
    if message is not None:
        raise ResponseParseError(f"the reply is an error object, not an answer: {message}")
    choices = data.get("choices")
    if not isinstance(choices, list) or not choices:
        raise ResponseParseError("the reply holds no choices")
    reply.choices = len(choices)
    if len(choices) > 1:
        return reply  # read_reply refuses it; the record keeps the whole body
    choice = choices[0]
    if not isinstance(choice, dict) or not isinstance(choice.get("message"), dict):
        raise ResponseParseError("the reply's choice holds no message object")
    if choice.get("index", 0) != 0:
        raise ResponseParseError(f"the reply's only choice has index {quote_untrusted(choice.get('index'), 20)}, not 0")
    msg = choice["message"]
    reply.finish_reason = _choice_finish_reason(choice)
    for key in ("tool_calls", "function_call"):
        if msg.get(key):
            raise ResponseParseError(f"the reply calls a tool ({key}); no tool was offered, only a JSON answer is read")
    if msg.get("refusal"):
        raise ResponseParseError(f"the model declined to answer: {quote_untrusted(msg['refusal'], _QUOTE)}")
    if msg.get("role", "assistant") != "assistant":
        raise ResponseParseError(f"the reply's message has role {quote_untrusted(msg.get('role'), 20)}, not assistant")
    reply.text = _content(msg)
    reply.reasoning = _reasoning(msg)
    return reply


def reply_from_chat_completion(body: bytes | str, *, origin: str | None = None) -> BackendReply:
    """Read a chat-completion response body strictly (see the module docstring); never raises."""
    reply = BackendReply(text="", origin=origin, usage_known=False)  # known once read (a refused body: never)
    try:
        if isinstance(body, (bytes, bytearray)):
            try:
                raw = body.decode("utf-8")
            except UnicodeDecodeError:
                raw = body.decode("utf-8", "replace")
                raise ResponseParseError("the reply's body is not valid UTF-8") from None
        else:
            raw = str(body)
        if len(raw) > MAX_BODY_BYTES:
            raise ResponseParseError(f"the reply's body is {len(raw)} characters long; "
                                     f"at most {MAX_BODY_BYTES} are read")
        objects = find_objects(raw, most=1)
        if len(objects) != 1 or raw[:objects[0][1]].strip() or raw[objects[0][2]:].strip():
            raise ResponseParseError("the reply's body is not exactly one JSON object")
        _check_strings(objects[0][0])
        reply = _read(objects[0][0], reply)
        if reply.choices is not None and reply.choices > 1:
            reply.text = raw[:MAX_RESPONSE_CHARS]  # every plan stays on record
        return reply
    except ResponseParseError as error:
        problem = str(error)
    except Exception as error:  # a body that breaks the reader is refused, never a crash
        problem = f"the reply could not be read ({type(error).__name__})"
    reply.text = raw[:MAX_RESPONSE_CHARS]
    reply.envelope_error = problem.replace("answer", "reply") if problem.startswith("answer") else problem
    reply.reasoning = None
    return reply
