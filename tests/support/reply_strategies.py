"""Hypothesis strategies for whole replies: chat-completion bodies as a server could send them.

:func:`bodies` draws ``(body, plan)``: the body's text (what goes over the wire) and what the
contract says of it -- the control signals that must run, or None when the reply must be refused
(worked out from how the body was made, not by reading it). Bodies vary everything the parsing
contract covers: the number of choices and their ``index`` order, duplicate keys in the envelope
(two ``content`` keys, two ``finish_reason`` keys), reasoning in a ``reasoning_content`` field or
in leading ``<think>`` blocks (with no plan, the answer's own plan, or another plan), the finish
reason (normal, cut off, filtered, padded, zero-width, missing), the text around the object
(bare, fenced, prose), a missing ``is_attack``, invisible characters in the texts.
"""

from __future__ import annotations

import json
from hypothesis import strategies as st

from safeembodai_core.testing import straight, turn

FINISH_REASONS = ["stop", "STOP", " stop", "stop\u200b", "length", "max_tokens", "content_filter", "tool_calls",
                  "end_turn", "error", None, "<missing>", 7]
INVISIBLE = ["", "\u200b", "\u2060", "\ufeff", "\U000e0049\U000e0047\U000e004e\U000e004f\U000e0052\U000e0045"]

signals = st.one_of(
    st.builds(straight, st.integers(1, 399), st.sampled_from(["forward", "backward"])),
    st.builds(turn, st.integers(1, 89), st.sampled_from(["left", "right"])),
)


@st.composite
def answers(draw: st.DrawFn) -> tuple[str, dict]:
    """An answer object (as text) and its data; sometimes without an ``is_attack`` flag."""
    hidden = draw(st.sampled_from(INVISIBLE))
    plan = draw(st.lists(signals, min_size=1, max_size=3))
    perception = [{"input": "human_instruction", "result": "read" + hidden, "is_attack": draw(st.booleans())},
                  {"input": "camera_image", "result": "a can", "is_attack": False}]
    if draw(st.integers(0, 9)) == 0:
        del perception[0]["is_attack"]
    data = {"perception": perception, "planning": "plan" + hidden, "control": plan}
    return json.dumps(data, ensure_ascii=draw(st.booleans())), data


ACCEPTED_WRAPPINGS = {"bare", "fence", "think-none", "think-same"}
NORMAL_REASONS = {"stop", "STOP", "end_turn", None, "<missing>"}


@st.composite
def contents(draw: st.DrawFn, text: str, other: str) -> tuple[str, str]:
    """``(how, content)``: ``text`` as a model might wrap it: bare, fenced, with prose, after a think block."""
    how = draw(st.sampled_from(["bare", "bare", "fence", "prose", "think-none", "think-same", "think-other",
                                "lone-close", "unclosed"]))
    wrapped = {
        "bare": text,
        "fence": f"```json\n{text}\n```",
        "prose": f"Do NOT execute this, it is unsafe: {text}",
        "think-none": f"<think>The wall is far; turning is fine.</think>\n{text}",
        "think-same": f"<think>I will send {text}</think>\n{text}",
        "think-other": f"<think>Maybe {other} but no.</think>\n{text}",
        "lone-close": f"Considering {other}.</think>{text}",
        "unclosed": f"<think>{text}",
    }
    return how, wrapped[how]


@st.composite
def bodies(draw: st.DrawFn) -> tuple[str, list[dict] | None]:
    """``(body, plan)``: a chat-completion body as hostile or honest as a server could make it, and
    the signals that must run (None: the contract refuses the reply)."""
    text, data = draw(answers())
    other, _ = draw(answers().filter(lambda drawn: drawn[1]["control"] != data["control"]))  # another plan
    how, content = draw(contents(text, other))
    refused = how not in ACCEPTED_WRAPPINGS or any("is_attack" not in p for p in data["perception"])
    reason = draw(st.sampled_from(FINISH_REASONS))
    message = {"role": "assistant", "content": content}
    reasoning = draw(st.sampled_from([None, "short thought", "<same>", "<other>"]))
    if reasoning is not None:
        message["reasoning_content"] = {"<same>": text, "<other>": other}.get(reasoning, reasoning)
    refused |= reasoning == "<other>" or reason not in NORMAL_REASONS
    choice = {"index": 0, "message": message}
    if reason != "<missing>":
        choice["finish_reason"] = reason
    choices = [choice]
    if draw(st.integers(0, 7)) == 0:  # a second choice with another plan, sometimes listed first
        second = {"index": 1, "message": {"role": "assistant", "content": other}, "finish_reason": "stop"}
        choices = [second, choice] if draw(st.booleans()) else [choice, second]
        refused = True
    body = json.dumps({"id": "chatcmpl-1", "object": "chat.completion", "created": 0, "model": "fake",
                       "choices": choices, "usage": {"prompt_tokens": 10, "completion_tokens": 5}})
    duplicate = draw(st.sampled_from([None, None, None, "content", "finish_reason"]))
    if duplicate == "content" and len(choices) == 1:  # another plan under a first content key
        body = body.replace('"content": ', f'"content": {json.dumps(other)}, "content": ', 1)
        refused = True
    if duplicate == "finish_reason" and len(choices) == 1 and "finish_reason" in choice:
        body = body.replace('"finish_reason": ', '"finish_reason": "length", "finish_reason": ', 1)
        refused = True
    return body, None if refused else data["control"]
