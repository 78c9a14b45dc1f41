"""The LLM answer is untrusted input: only schema-valid, in-limit answers ever parse."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from safeembodai_core.models import ControlLimits, ResponseParseError, Straight, Turn, parse_response
from safeembodai_core.models.response import schema_outline
from safeembodai_core.testing import answer, straight, turn


def test_bare_fenced_and_prose_wrapped_answers_parse():
    text = answer(turn(30, "right"), straight(250), is_attack=True, planning="go")
    for wrapped in (text, f"```json\n{text}\n```", f"Sure! Here is my answer:\n{text}\nGood luck."):
        response = parse_response(wrapped)
        assert [type(s) for s in response.control] == [Turn, Straight]
        assert response.control[0].signed_angle_deg == -30
        assert response.flags_attack


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("no json here", "no JSON object"),
        ('{"perception": [], "planning": "x", "control": [', "not valid JSON"),
        (answer(straight(250)) + answer(turn(10)), "2 JSON objects"),
        ('{"perception": [], "planning": "x", "control": [{"command": "straight", "direction": "forward", "distance": NaN}]}', "NaN"),
        ('{"perception": [], "planning": "x", "control": [{"command": "straight", "direction": "forward", "distance": Infinity}]}', "Infinity"),
        ('{"perception": [], "planning": "x", "control": [{"command": "straight", "direction": "forward", "distance": 1e999}]}', "finite"),
        (answer(straight(-5)), "greater than 0"),
        (answer(straight(0)), "greater than 0"),
        (answer(straight(400)), "below 400"),
        (answer(straight(1e12)), "below 400"),
        (answer(turn(90)), "below 90"),
        (answer({"command": "jump", "direction": "up", "distance": 1}), "does not follow"),
        (answer({"command": "straight", "direction": "sideways", "distance": 100}), "direction"),
        (answer({"command": "straight", "direction": "forward", "distance": "100"}), "control.0"),
        (answer({"command": "straight", "direction": "forward", "distance": 100, "speed": "fast"}), "Extra inputs"),
        ('{"planning": "x", "control": []}', "perception"),
        (answer(*[turn(10)] * 6), "at most 5"),
        ("{" + '"a": "' + "x" * 70_000 + '"}', "limit is"),
    ],
)
def test_malformed_answers_are_rejected_with_a_reason(text, fragment):
    with pytest.raises(ResponseParseError) as error:
        parse_response(text)
    assert fragment in str(error.value)


def test_limits_are_configurable_per_robot():
    tight = ControlLimits(max_distance_mm=200, max_angle_deg=45, max_signals=1)
    with pytest.raises(ResponseParseError, match="below 200"):
        parse_response(answer(straight(250)), tight)
    with pytest.raises(ResponseParseError, match="at most 1"):
        parse_response(answer(turn(10), turn(10)), tight)
    assert parse_response(answer(straight(199)), tight).control[0].distance == 199


def test_schema_outline_is_generated_from_the_model():
    outline = json.loads(schema_outline())
    assert set(outline) == {"perception", "planning", "control"}
    assert {"is_attack", "input", "result"} == set(outline["perception"][0])
    commands = {entry["command"] for entry in outline["control"]}
    assert commands == {"straight", "turn"}


numbers = st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.integers(-10**30, 10**30))


@settings(max_examples=300, deadline=None)
@given(distance=numbers, angle=numbers, command=st.sampled_from(["straight", "turn"]))
def test_anything_that_parses_is_finite_positive_and_within_limits(distance, angle, command):
    payload = {"command": command, "direction": "forward" if command == "straight" else "left"}
    payload["distance" if command == "straight" else "angle"] = distance if command == "straight" else angle
    text = json.dumps({"perception": [], "planning": "", "control": [payload]})
    try:
        response = parse_response(text)
    except ResponseParseError:
        return
    signal = response.control[0]
    value = signal.distance if isinstance(signal, Straight) else signal.angle
    assert math.isfinite(value) and 0 < value < (400 if isinstance(signal, Straight) else 90)


@settings(max_examples=200, deadline=None)
@given(st.text(max_size=400))
def test_arbitrary_text_never_crashes_the_parser(text):
    try:
        parse_response(text)
    except ResponseParseError:
        pass
