"""Prompt -> chat messages, and the response formats sent for JSON output."""

from __future__ import annotations

import base64
import json

import pytest

from safeembodai_core.models import ControlLimits, ImagePart, Prompt, TextPart, parse_response
from safeembodai_core.testing import answer, straight, turn
from safeembodai_plugins.backends.messages import chat_messages, decoding_schema, response_format

PNG = b"\x89PNG\r\n\x1a\nfake"


def _prompt() -> Prompt:
    return Prompt(system="SYSTEM TEXT", user=(TextPart("user", "USER TEXT"), ImagePart("camera_image", PNG),
                                              ImagePart("lidar_image", PNG + b"2")))


def test_images_become_data_urls_with_the_detail_asked_for():
    messages = chat_messages(_prompt(), detail="high")
    assert [m["role"] for m in messages] == ["system", "user"]
    parts = messages[1]["content"]
    images = [p for p in parts if p["type"] == "image_url"]
    assert len(images) == 2
    assert images[0]["image_url"]["url"] == "data:image/png;base64," + base64.b64encode(PNG).decode()
    assert {p["image_url"]["detail"] for p in images} == {"high"}
    assert parts[0] == {"type": "text", "text": "USER TEXT"}


def test_fold_system_prompt_puts_it_first_in_the_user_turn():
    messages = chat_messages(_prompt(), fold_system=True, send_images=False)
    assert [m["role"] for m in messages] == ["user"]
    assert messages[0]["content"] == "SYSTEM TEXT\n\nUSER TEXT"  # text only: a plain string


def test_text_only_prompt_sends_a_plain_string():
    prompt = Prompt(system="S", user=(TextPart("user", "U"),))
    assert chat_messages(prompt)[1]["content"] == "U"


def test_decoding_schema_requires_every_field_and_caps_text_by_the_token_budget():
    schema = decoding_schema(ControlLimits(max_signals=3))
    text = json.dumps(schema)
    assert "title" not in text and '"maxLength": 2000' not in text  # the contract's cap: too big a grammar
    assert 0 < schema["properties"]["planning"]["maxLength"] <= 1000
    straight_def = schema["$defs"]["Straight"]
    assert set(straight_def["required"]) == {"command", "direction", "distance", "justification"}
    assert schema["properties"]["control"]["maxItems"] == 3
    assert schema["additionalProperties"] is False


@pytest.mark.parametrize("mode,expected_type", [("json_object", "json_object"), ("json_schema", "json_schema"),
                                                ("json_schema_enum", "json_object")])
def test_response_formats(mode, expected_type):
    fmt = response_format(mode)
    assert fmt["type"] == expected_type
    if mode == "json_schema":
        assert fmt["json_schema"]["schema"] == decoding_schema()
    if mode == "json_schema_enum":
        assert fmt["schema"] == decoding_schema(bounds="enum")
    assert response_format("none") is None


def test_an_answer_shaped_by_the_decoding_schema_parses():
    data = json.loads(answer(turn(30), straight(200)))
    for signal in data["control"]:
        assert set(signal) == set(decoding_schema()["$defs"][signal["command"].title()]["properties"])
    assert parse_response(json.dumps(data)).control[1].distance == 200
