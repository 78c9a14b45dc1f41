"""Answers cut off at ``max_tokens``: the decoding schema caps every text field so that the
longest answer its grammar admits fits in the backend's ``max_tokens``, while the parser keeps the
full contract (2,000 characters of text)."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from fake_openai import Reply
from safeembodai_plugins.backends.messages import (
    DEFAULT_MAX_TOKENS,
    MAX_GRAMMAR_TEXT,
    MIN_GRAMMAR_TEXT,
    decoding_schema,
    longest_answer_chars,
    response_format,
    text_caps,
)
from structlog.testing import capture_logs

from safeembodai_core.models import ControlLimits, Prompt, TextPart, parse_response
from safeembodai_core.models.control import MAX_TEXT
from safeembodai_core.testing import answer, straight, turn

LIMITS = [ControlLimits(), ControlLimits(max_distance_mm=250, max_angle_deg=45, max_signals=2),
          ControlLimits(max_distance_mm=5000, max_angle_deg=180, max_signals=10)]


def _texts(schema):
    entry, straight_def, turn_def = (schema["$defs"][name]["properties"]
                                     for name in ("PerceptionEntry", "Straight", "Turn"))
    return {"planning": schema["properties"]["planning"], "result": entry["result"], "input": entry["input"],
            "justification": straight_def["justification"], "justification (turn)": turn_def["justification"]}


@pytest.mark.parametrize("bounds", ["enum", "range"])
@pytest.mark.parametrize("limits,max_tokens", [(LIMITS[0], 1536), (LIMITS[1], 1024), *(
    (limits, max_tokens) for limits in LIMITS for max_tokens in (DEFAULT_MAX_TOKENS, 4096))])
def test_the_longest_answer_fits_in_max_tokens(bounds, limits, max_tokens):
    schema = decoding_schema(limits, bounds, max_tokens=max_tokens)
    assert all("maxLength" in node for node in _texts(schema).values())
    assert longest_answer_chars(schema) <= max_tokens


def test_the_budget_goes_mostly_to_planning_and_grows_with_max_tokens():
    small, large = (dict(text_caps(max_tokens=n)) for n in (DEFAULT_MAX_TOKENS, 4096))
    assert small["planning"] == 2 * small["result"] == 4 * small["justification"] >= 256
    assert large["planning"] > small["planning"]
    assert response_format("json_schema_enum", max_tokens=4096)["schema"] == decoding_schema(bounds="enum",
                                                                                            max_tokens=4096)


def test_no_cap_exceeds_what_the_llama_cpp_python_server_parses():
    caps = dict(text_caps(max_tokens=32_768))
    assert max(caps.values()) == MAX_GRAMMAR_TEXT < MAX_TEXT


def test_a_budget_too_small_for_the_shortest_caps_is_logged():
    with capture_logs() as logs:
        caps = dict(text_caps(ControlLimits(max_signals=7), max_tokens=400))
    assert set(caps.values()) <= {MIN_GRAMMAR_TEXT, 32}
    assert [entry["event"] for entry in logs] == ["decoding.budget_short"]


def test_the_truncated_answers_of_the_recorded_run_would_have_been_closed_off():
    # runs/real-smollm2-135m-instruct-20261201-185723: all three answers cut at max_tokens looped in planning
    looping = "turn left 45 deg; turn right 45 deg; " * 40
    assert len(looping) > dict(text_caps())["planning"]


def test_the_parser_keeps_the_full_contract():
    long_plan = json.loads(answer(turn(30)))
    long_plan["planning"] = "p" * MAX_TEXT
    assert parse_response(json.dumps(long_plan)).planning == "p" * MAX_TEXT


@pytest.mark.slow
def test_the_backend_sends_caps_sized_from_its_own_max_tokens(built_plugins, fake_server):
    fake_server.default = Reply(answer(straight(100)))
    prompt = Prompt(system="S", user=(TextPart("user", "U"),))
    for max_tokens in (1536, 4096):
        backend = built_plugins.registry.build("llm_backend", "local", {
            "api_base": fake_server.url, "timeout_s": 5.0, "max_tokens": max_tokens})
        backend.complete(prompt, np.random.default_rng(0))
    sent = [r.body for r in fake_server.requests]
    assert [b["max_tokens"] for b in sent] == [1536, 4096]
    for body in sent:
        schema = body["response_format"]["schema"]
        assert schema == decoding_schema(bounds="enum", max_tokens=body["max_tokens"])
        assert longest_answer_chars(schema) <= body["max_tokens"]


def test_text_fields_admit_no_control_character_quote_or_escape_and_no_more_than_the_cap():
    # llama-cpp-python 0.3.x's own string rule lets a raw newline into a string (invalid JSON);
    # it reads the pattern before maxLength
    for name, node in _texts(decoding_schema()).items():
        pattern, cap = re.compile(node["pattern"]), node["maxLength"]
        assert pattern.match("a" * cap) and pattern.match("é" * cap) and pattern.match(""), name
        assert not pattern.match("a" * (cap + 1)), name
        for bad in ("line\nbreak", "tab\there", 'quote"', "back\\slash", "\x00"):
            assert not pattern.match(bad), (name, bad)
