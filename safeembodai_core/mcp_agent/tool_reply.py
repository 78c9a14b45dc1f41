"""A chat completion that calls tools, read strictly: what the model said and which tools it called.

The trial loop's reader (:mod:`safeembodai_core.models.chat_completion`) refuses ``tool_calls``: no
tool is offered there. An MCP agent offers tools, so its replies are read here, by the same rules where
they apply: exactly one choice; the message's ``content`` text or ``null``; a ``refusal`` or a reply
the provider did not end normally (``length``, ``content_filter``) is refused; each tool call has an
``id``, type ``function``, the name of an *offered* tool and ``arguments`` that are one strict JSON
object (:func:`~safeembodai_core.models.strict_json.read_json_document`: no duplicate key, no NaN, no
huge number, no lone surrogate); at most :data:`MAX_CALLS` calls; usage as
:func:`~safeembodai_core.models.chat_completion.read_usage` reads it. A reply that breaks a rule raises
:class:`~safeembodai_core.models.ResponseParseError`, its message written for the model to read on a retry.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Collection

from ..models import ResponseParseError, TokenUsage
from ..models.chat_completion import read_usage
from ..models.strict_json import read_json_document
from ..trust.quoting import quote_untrusted

MAX_CALLS = 8
MAX_CONTENT_CHARS = 16_000
MAX_ARGUMENT_CHARS = 64_000
#: Ends a reply may have: the model finished, or stopped to call tools.
NORMAL_ENDS = ("stop", "tool_calls", "function_call", None)


@dataclass(frozen=True)
class ToolCall:
    """One call the model asked for: its ``id`` (to answer it), the tool and its arguments."""

    id: str
    name: str
    arguments: dict[str, Any]


@dataclass(frozen=True)
class ToolReply:
    """A reply read: the model's text, its calls, how it ended, its usage (None: not reported) and model."""

    content: str
    calls: list[ToolCall] = field(default_factory=list)
    finish_reason: str | None = None
    usage: TokenUsage | None = None
    model: str | None = None


def _text(value: Any, what: str, most: int) -> str:
    if not isinstance(value, str):
        raise ResponseParseError(f"{what} must be text, got {type(value).__name__}")
    if len(value) > most:
        raise ResponseParseError(f"{what} is longer than {most} characters")
    return value


def _call(raw: Any, offered: Collection[str]) -> ToolCall:
    if not isinstance(raw, dict) or raw.get("type", "function") != "function" or not isinstance(raw.get("function"),
                                                                                              dict):
        raise ResponseParseError("each tool call must be a function call")
    function = raw["function"]
    name = _text(function.get("name"), "a tool call's name", 128)
    if name not in offered:
        raise ResponseParseError(f"tool {quote_untrusted(name, 60)} was not offered; call one of "
                                 f"{', '.join(sorted(offered))}")
    text = _text(function.get("arguments") or "{}", f"the arguments of {name}", MAX_ARGUMENT_CHARS)
    arguments = read_json_document(text, f"the arguments of {name}")
    if not isinstance(arguments, dict):
        raise ResponseParseError(f"the arguments of {name} must be one JSON object")
    return ToolCall(_text(raw.get("id") or "", "a tool call's id", 256), name, arguments)


def read_tool_reply(body: Any, offered: Collection[str]) -> ToolReply:
    """``body`` (a chat completion as a dict) read strictly (module docstring)."""
    if not isinstance(body, dict):
        raise ResponseParseError("the reply is not a chat completion")
    choices = body.get("choices")
    if not isinstance(choices, list) or len(choices) != 1 or not isinstance(choices[0], dict):
        raise ResponseParseError("the reply must hold exactly one choice")
    choice = choices[0]
    finish = choice.get("finish_reason")
    if finish not in NORMAL_ENDS:
        raise ResponseParseError(f"the reply did not end normally (finish_reason {quote_untrusted(finish, 40)})")
    message = choice.get("message")
    if not isinstance(message, dict):
        raise ResponseParseError("the reply's choice holds no message")
    if message.get("refusal"):
        raise ResponseParseError("the model refused to answer")
    content = message.get("content")
    content = "" if content is None else _text(content, "the reply's content", MAX_CONTENT_CHARS)
    raw_calls = message.get("tool_calls") or []
    if not isinstance(raw_calls, list) or len(raw_calls) > MAX_CALLS:
        raise ResponseParseError(f"a reply may call at most {MAX_CALLS} tools")
    calls = [_call(raw, offered) for raw in raw_calls]
    if len({call.id for call in calls}) != len(calls):
        raise ResponseParseError("two tool calls of one reply share an id")
    model = body.get("model")
    return ToolReply(content, calls, finish if isinstance(finish, str) else None, read_usage(body.get("usage")),
                     model[:200] if isinstance(model, str) else None)
