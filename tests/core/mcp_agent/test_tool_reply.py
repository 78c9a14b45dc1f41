"""A chat completion that calls tools, read strictly: one choice, offered tools only, strict JSON arguments."""

from __future__ import annotations

import json

import pytest

from safeembodai_core.mcp_agent.tool_reply import MAX_CALLS, read_tool_reply
from safeembodai_core.models import ResponseParseError

OFFERED = {"subscribe_once", "publish_for_durations"}


def body(*calls, content=None, finish="tool_calls", choices=None, **extra):
    message = {"role": "assistant", "content": content,
               "tool_calls": [{"id": f"c{k}", "type": "function", "function": {"name": name, "arguments": arguments}}
                              for k, (name, arguments) in enumerate(calls)] or None}
    return {"id": "x", "model": "fake-model", "choices": choices or [{"index": 0, "message": message,
                                                                       "finish_reason": finish}],
            "usage": {"prompt_tokens": 12, "completion_tokens": 3}, **extra}


def test_a_reply_with_calls_is_read():
    reply = read_tool_reply(body(("subscribe_once", '{"topic": "/scan", "msg_type": "sensor_msgs/msg/LaserScan"}')),
                            OFFERED)
    assert [(c.id, c.name, c.arguments["topic"]) for c in reply.calls] == [("c0", "subscribe_once", "/scan")]
    assert reply.usage.prompt_tokens == 12 and reply.model == "fake-model" and reply.finish_reason == "tool_calls"


def test_a_reply_without_calls_is_its_text():
    reply = read_tool_reply(body(content="The can is reached.", finish="stop"), OFFERED)
    assert reply.calls == [] and reply.content == "The can is reached."


@pytest.mark.parametrize("arguments, why", [
    ('{"topic": "/scan", "topic": "/cmd_vel"}', "more than once"),
    ('{"durations": [NaN]}', None),
    ('{"durations": [1e999]}', "too large"),
    ('[1, 2]', "one JSON object"),
    ('{"a": 1} {"b": 2}', "more than one"),
    ('{"topic": "\\ud800"}', None),
])
def test_arguments_that_are_not_one_strict_json_object_are_refused(arguments, why):
    with pytest.raises(ResponseParseError, match=why):
        read_tool_reply(body(("publish_for_durations", arguments)), OFFERED)


def test_a_tool_not_offered_is_refused_by_name():
    with pytest.raises(ResponseParseError, match="call_service.*was not offered"):
        read_tool_reply(body(("call_service", "{}")), OFFERED)


@pytest.mark.parametrize("broken", [
    {"choices": []},
    {"choices": [{"index": 0, "message": {"content": "a"}, "finish_reason": "stop"}] * 2},
    {"choices": [{"index": 0, "message": {"content": "cut", "tool_calls": None}, "finish_reason": "length"}]},
    {"choices": [{"index": 0, "message": {"content": None, "refusal": "no"}, "finish_reason": "stop"}]},
    {"choices": [{"index": 0, "message": {"content": 3}, "finish_reason": "stop"}]},
    "not a body",
])
def test_envelopes_that_break_a_rule_are_refused(broken):
    with pytest.raises(ResponseParseError):
        read_tool_reply(broken if isinstance(broken, str) else {"id": "x", **broken}, OFFERED)


def test_too_many_calls_or_a_shared_id_are_refused():
    with pytest.raises(ResponseParseError, match="at most"):
        read_tool_reply(body(*[("subscribe_once", "{}")] * (MAX_CALLS + 1)), OFFERED)
    twice = body(("subscribe_once", "{}"), ("subscribe_once", "{}"))
    for call in twice["choices"][0]["message"]["tool_calls"]:
        call["id"] = "same"
    with pytest.raises(ResponseParseError, match="share an id"):
        read_tool_reply(twice, OFFERED)


def test_unusable_usage_is_none_not_zero():
    reply = read_tool_reply(json.loads(json.dumps(body(("subscribe_once", "{}"), usage={"total_tokens": 5}))), OFFERED)
    assert reply.usage is None
