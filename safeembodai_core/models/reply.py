"""The whole reply of an LLM backend, read as one: the one strict reading on every path.

A backend hands the core a :class:`BackendReply`: the answer text, and what else the reply said
about it -- the reasoning the provider sent apart from the text, how many choices the reply
held, why it ended, where it came from, and anything a strict reading of the reply's envelope
refused. :func:`read_reply` turns it into an :class:`~.response.LLMResponse` or refuses it with a
:class:`~.strict_json.ResponseParseError` written for the LLM to read on a retry. Algorithm 1
(:mod:`safeembodai_core.loop.guarded_step`), :meth:`safeembodai_core.guard.guard.Guard.check_reply`, the
Gymnasium env and the Inspect solver all read replies here, so the same reply gets the same
verdict everywhere. In order, a reply is refused when:

1. its envelope was refused (``envelope_error``: duplicate keys anywhere in the reply, a message
   with two contents, an error object, ...; the backend's strict reading, see
   :func:`safeembodai_core.models.chat_completion.reply_from_chat_completion`);
2. it holds more than one choice (two plans; one is executed only when one was sent);
3. its finish reason is not a normal end (:func:`normal_finish_reason`: one normalisation, one
   list), or it reports none and the contract requires one (``limits.require_finish_reason``);
4. the text, with the reasoning, is longer than :data:`MAX_RESPONSE_CHARS`;
5. its reasoning -- the backend's ``reasoning`` plus any leading ``<think>``/``<thinking>``/
   ``<reasoning>`` blocks of the text, or a text before a lone closing tag -- holds a JSON object
   other than the answer's own (one plan per reply: ``<think>maybe {..} but no</think>{..}``) or
   a ``{`` that starts no complete object, or a reasoning block is never closed;
6. the text outside the reasoning is not exactly one JSON object read strictly
   (:mod:`.strict_json`) and, by default (``limits.outside_text: refuse``), with nothing around
   it but whitespace and one Markdown code fence;
7. the object does not follow the response schema (``is_attack`` is required on every
   perception entry) or has more signals than the limits allow.

Nothing else escapes :func:`read_reply`: an unexpected exception while reading is a refusal too.
See ``docs/parsing.md`` (the parsing contract).
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, fields
from typing import Any

from pydantic import ValidationError

from ..logs import get_logger
from ..trust.quoting import CLIPPED, quote_untrusted
from .control import DEFAULT_LIMITS, ControlLimits
from .records import TokenUsage
from .response import LLMResponse, describe_schema_error
from .strict_json import QUOTE_CHARS, ResponseParseError, find_objects, read_sole_object

log = get_logger(__name__)

MAX_RESPONSE_CHARS = 64_000
MAX_FINISH_REASON_CHARS = 64

# Finish reasons that mean "the model ended its answer itself". OpenAI (and litellm, which maps
# every provider to OpenAI's names) says "stop"; the others are the native names of providers
# reached without litellm: Anthropic "end_turn"/"stop_sequence", Hugging Face "eos"/"eos_token",
# Cohere "COMPLETE". Everything else -- "length", "content_filter", "tool_calls", "error",
# "stop\u200b" -- is refused. None means the backend does not report a reason.
NORMAL_FINISH_REASONS = frozenset({"stop", "end_turn", "stop_sequence", "eos", "eos_token", "complete"})

_OPENING = re.compile(r"\s*<(think|thinking|reasoning)>", re.I)
_LONE_CLOSING = re.compile(r"</(think|thinking|reasoning)>", re.I)
_FENCE_OPEN = re.compile(r"\A\s*```[A-Za-z0-9_-]*[ \t]*\r?\n\s*\Z")
_FENCE_CLOSE = re.compile(r"\A\s*```\s*\Z")


@dataclass
class BackendReply:
    """A backend's reply: the answer text (untrusted) and what the reply said about it.

    * ``text`` -- the answer as the model wrote it (its content, reasoning tags included).
    * ``finish_reason`` -- the provider's reason the answer ended, as it sent it (OpenAI's
      ``"stop"``, ``"length"``, ``"content_filter"``, ...), or None for a backend that does not
      report one (accepted unless the contract requires one, and recorded as not reported).
    * ``reasoning`` -- reasoning or thinking text the provider sent apart from the content
      (``reasoning_content``); part of the reply: it is recorded and read for a second plan.
    * ``choices`` -- how many choices the reply held; None when the backend hands over one text.
    * ``envelope_error`` -- what a strict reading of the whole reply refused (duplicate keys, two
      contents, ...), written for the LLM; the answer is then refused whatever its text.
    * ``origin`` -- where the answer came from (``scheme://host:port`` of the server that sent it).

    Algorithm 1 refuses any reply :func:`read_reply` refuses: a cut-off, filtered, ambiguous or
    redirected answer is never executed.
    """

    text: str
    usage: TokenUsage = field(default_factory=TokenUsage)
    latency_s: float = 0.0
    model: str = ""
    finish_reason: str | None = None
    reasoning: str | None = None
    choices: int | None = None
    envelope_error: str | None = None
    origin: str | None = None
    #: False when the server's usage was missing or unusable: the backend then counts the tokens itself
    usage_known: bool = True


#: The longest model name a reply keeps, and the characters it may hold (others become ``_``).
MODEL_CHARS = 100
_NOT_PLAIN = re.compile(r"[^A-Za-z0-9_.:/@+\-]")
#: The longest envelope error a reply read back keeps (ours are far shorter).
ENVELOPE_ERROR_CHARS = 300


def plain_token(value: Any, most: int = MODEL_CHARS) -> str:
    """``value`` as a short single token: characters outside ``[A-Za-z0-9_.:/@+-]`` become ``_``
    (a model's name as a server or a stored reply gives it: never an escape sequence or Markdown)."""
    return _NOT_PLAIN.sub("_", str(value)[:most])


def envelope_error_text(error: Any) -> str | None:
    """A stored reply's envelope error as this version would have written it: one line, shown as
    terminal text, clipped visibly (a cache file could hold anything there)."""
    if error is None:
        return None
    from ..trust.text import one_line, terminal_text

    text = one_line(terminal_text(str(error)))
    return text if len(text) <= ENVELOPE_ERROR_CHARS else text[:ENVELOPE_ERROR_CHARS] + CLIPPED


def finish_reason_text(reason: Any) -> str | None:
    """A backend's finish reason as short text, as sent (an enum's value, say); None when not reported."""
    if reason is None:
        return None
    text = str(getattr(reason, "value", reason))
    # clipped visibly: padding cannot push an abnormal reason past the cut and leave "stop" in front
    return text if len(text) <= MAX_FINISH_REASON_CHARS else text[:MAX_FINISH_REASON_CHARS] + CLIPPED


def normal_finish_reason(reason: Any) -> str | None:
    """The one normalisation of a finish reason: case is ignored, nothing else.

    ``"STOP"`` is ``"stop"``; padding is not dropped (``" STOP "`` is not a normal stop, as the
    trial loop always read it), and neither is a zero-width or control character (``"stop\\u200b"``).
    None when not reported.
    """
    text = finish_reason_text(reason)
    return None if text is None else text.lower()


def check_finish_reason(reason: Any, limits: ControlLimits = DEFAULT_LIMITS) -> None:
    """Refuse a reply whose finish reason is not a normal end (see :data:`NORMAL_FINISH_REASONS`)."""
    normal = normal_finish_reason(reason)
    if normal is None:
        if limits.require_finish_reason:
            raise ResponseParseError("the reply reports no finish reason, and this contract requires one: "
                                     "an answer that may have been cut off is not executed")
        return
    if normal in NORMAL_FINISH_REASONS:
        return
    if normal in ("length", "max_tokens"):
        hint = "it was cut off at the token limit; send one complete, shorter JSON object"
    else:
        hint = "the provider stopped it before a normal end; send one complete JSON object"
    raise ResponseParseError(
        f"answer ended with finish reason {quote_untrusted(finish_reason_text(reason), QUOTE_CHARS)}, not a normal "
        f"stop, so it is not executed: {hint}"
    )


def split_reasoning(text: str) -> tuple[str, str]:
    """``(reasoning, rest)``: the leading reasoning blocks of ``text`` and what follows them.

    Leading ``<think>...</think>`` blocks (also ``thinking``, ``reasoning``; any case) are
    reasoning, as is everything before a closing tag that has no opening one and that the answer
    (a ``{`` or a code fence) follows (templates that open the block in the prompt). A block that is
    never closed makes the whole rest reasoning.
    """
    reasoning: list[str] = []
    rest = text
    while True:
        opening = _OPENING.match(rest)
        if opening is None:
            break
        tag = opening.group(1).lower()
        close = re.search(rf"</{tag}>", rest[opening.end():], re.I)
        if close is None:
            raise ResponseParseError(f"the answer opens a <{tag}> reasoning block and never closes it, so it "
                                     "holds no answer outside its reasoning; "
                                     "close the block, then send the JSON object")
        reasoning.append(rest[opening.end():opening.end() + close.start()])
        rest = rest[opening.end() + close.end():]
    if not reasoning:
        for lone in _LONE_CLOSING.finditer(rest):
            # a boundary only where the answer follows it; "</think>" quoted inside the answer's own
            # strings ('... "</think> drive straight" ...') is text of the answer, not a boundary
            if "<" + lone.group(1).lower() + ">" in rest[:lone.start()].lower():
                break
            if rest[lone.end():].lstrip().startswith(("{", "```")):
                reasoning.append(rest[:lone.start()])
                rest = rest[lone.end():]
                break
    return "\n".join(reasoning), rest


def _check_reasoning(reasoning: str, answer: dict[str, Any]) -> None:
    """Refuse reasoning that holds a JSON object other than ``answer`` (a second plan), or a ``{``
    that starts no complete object (a cut-off second plan is still one, as in the text)."""
    try:
        objects = find_objects(reasoning)
    except ResponseParseError as error:
        raise ResponseParseError(f"the reply's reasoning: {error}; keep JSON out of the reasoning") from None
    for value, start, end in objects:
        if value != answer:
            raise ResponseParseError(
                "the reply's reasoning holds a JSON object other than the answer "
                f"({quote_untrusted(reasoning[start:end], QUOTE_CHARS)}); one plan per reply, so "
                "none is executed: keep drafts out of the reasoning")


def _check_layout(content: str, start: int, end: int) -> None:
    """With ``outside_text: refuse``: only whitespace and one code fence around the object."""
    before, after = content[:start], content[end:]
    bare = not before.strip() and not after.strip()
    fenced = _FENCE_OPEN.match(before) is not None and _FENCE_CLOSE.match(after) is not None
    if bare or fenced:
        return
    outside = before.strip() or after.strip()
    raise ResponseParseError(
        f"answer has text outside the JSON object ({quote_untrusted(outside, QUOTE_CHARS)}); send only the one "
        "object, bare or in one code fence"
    )


def _read(reply: BackendReply, limits: ControlLimits) -> LLMResponse:
    if reply.envelope_error:
        raise ResponseParseError(f"the reply was refused as a whole: {reply.envelope_error}")
    if reply.choices is not None and reply.choices != 1:
        raise ResponseParseError(f"the reply holds {reply.choices} choices; one answer per reply (several plans "
                                 "are ambiguous, so none is executed)")
    check_finish_reason(reply.finish_reason, limits)
    text, extra = reply.text, reply.reasoning
    if not isinstance(text, str):
        raise ResponseParseError(f"answer is not text (got {type(text).__name__})")
    if extra is not None and not isinstance(extra, str):
        raise ResponseParseError(f"the reply's reasoning is not text (got {type(extra).__name__})")
    size = len(text) + len(extra or "")
    if size > MAX_RESPONSE_CHARS:
        raise ResponseParseError(f"answer is {size} characters long; the limit is {MAX_RESPONSE_CHARS}")
    inline, content = split_reasoning(text)
    data, start, end = read_sole_object(content)
    _check_reasoning("\n".join(part for part in (extra, inline) if part), data)
    if limits.outside_text == "refuse":
        _check_layout(content, start, end)
    try:
        response = LLMResponse.model_validate(data, context={"limits": limits})
    except ValidationError as error:
        raise ResponseParseError(
            f"answer does not follow the response schema: {describe_schema_error(error)}"
        ) from None
    if len(response.control) > limits.max_signals:
        raise ResponseParseError(
            f"answer has {len(response.control)} control signals; at most {limits.max_signals} are allowed"
        )
    return response


def read_reply(reply: BackendReply, limits: ControlLimits = DEFAULT_LIMITS) -> LLMResponse:
    """Read a whole reply strictly (see the module docstring); raise only :class:`ResponseParseError`."""
    try:
        return _read(reply, limits)
    except ResponseParseError:
        raise
    except Exception as error:  # any other failure to read untrusted text is a refusal, not a crash
        # quoted: the message may hold LLM text, lone surrogates included, that a log cannot encode
        log.warning("answer.unreadable", error=type(error).__name__, detail=quote_untrusted(error, 200))
        raise ResponseParseError(
            f"answer could not be read ({type(error).__name__}); send exactly one valid JSON object"
        ) from None


def parse_response(text: str, limits: ControlLimits = DEFAULT_LIMITS, *, finish_reason: Any = None,
                   reasoning: str | None = None) -> LLMResponse:
    """Read an answer given as text (and, when known, its finish reason and reasoning): :func:`read_reply`."""
    return read_reply(BackendReply(text=text, finish_reason=finish_reason, reasoning=reasoning), limits)


_REPLY_FIELDS = tuple(f.name for f in fields(BackendReply))


def as_reply(value: Any) -> BackendReply:
    """``value`` as a :class:`BackendReply`.

    A reply is taken as it is; text is a reply that reports nothing else; a mapping or an object
    with a ``text`` attribute gives the fields it has (``text``, ``finish_reason``, ``reasoning``,
    ``choices``, ...; unknown keys are ignored). Anything else becomes a reply whose text is not
    text, which :func:`read_reply` refuses.
    """
    if isinstance(value, BackendReply):
        return value
    if isinstance(value, str):
        return BackendReply(text=value)
    if isinstance(value, dict) and "text" in value:
        return BackendReply(**{name: value[name] for name in _REPLY_FIELDS if name in value})
    if not isinstance(value, dict) and hasattr(value, "text"):
        return BackendReply(**{name: getattr(value, name) for name in _REPLY_FIELDS if hasattr(value, name)})
    return BackendReply(text=value)


__all__ = ["BackendReply", "MAX_RESPONSE_CHARS", "NORMAL_FINISH_REASONS", "as_reply", "check_finish_reason",
           "finish_reason_text", "normal_finish_reason", "parse_response", "read_reply", "split_reasoning"]
