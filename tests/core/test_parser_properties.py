"""Property tests of the strict answer parser: hostile answers are refused, valid ones read exactly.

Every test generates answers, feeds them to :func:`parse_response` and accepts exactly two
outcomes: a :class:`ResponseParseError`, or the signals an independent strict reading gives --
the generated answer itself, which the test knows. Any other exception fails the test.
"""

from __future__ import annotations

import json
import math
from typing import Any

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from safeembodai_core.models import DEFAULT_LIMITS, ControlLimits, LLMResponse, ResponseParseError, parse_response
from safeembodai_core.models.strict_json import MAX_DEPTH, MAX_MAGNITUDE, MAX_NUMBER_CHARS

FAST = settings(max_examples=120, deadline=None, suppress_health_check=[HealthCheck.too_slow])
LIMITS = DEFAULT_LIMITS
LENIENT = ControlLimits(outside_text="allow")

# Text the strict reading accepts inside strings: valid Unicode, no C0 control but tab/LF/CR.
_TEXT_CHARS = st.characters(blacklist_categories=("Cs",), blacklist_characters=[
    chr(c) for c in range(32) if chr(c) not in "\t\n\r"])
texts = st.text(_TEXT_CHARS, max_size=40)
prose = st.text(st.characters(blacklist_categories=("Cs",), blacklist_characters="{"), max_size=40)


def _open_interval(upper: float) -> st.SearchStrategy[float]:
    return st.one_of(
        st.integers(1, int(math.ceil(upper)) - 1).map(float),
        st.floats(0, upper, exclude_min=True, exclude_max=True, allow_nan=False),
    )


straights = st.fixed_dictionaries({
    "command": st.just("straight"), "direction": st.sampled_from(["forward", "backward"]),
    "distance": _open_interval(LIMITS.max_distance_mm), "justification": texts,
})
turns = st.fixed_dictionaries({
    "command": st.just("turn"), "direction": st.sampled_from(["left", "right"]),
    "angle": _open_interval(LIMITS.max_angle_deg), "justification": texts,
})
perception = st.fixed_dictionaries({
    "input": st.text(_TEXT_CHARS, max_size=20), "result": texts, "is_attack": st.booleans(),
})
valid_answers = st.fixed_dictionaries({
    "perception": st.lists(perception, max_size=3),
    "planning": texts,
    "control": st.lists(st.one_of(straights, turns), max_size=LIMITS.max_signals),
})


def serialise(data: Any, draw_style: tuple[bool, int | None]) -> str:
    ensure_ascii, indent = draw_style
    return json.dumps(data, ensure_ascii=ensure_ascii, indent=indent)


styles = st.tuples(st.booleans(), st.sampled_from([None, 0, 2]))


@st.composite
def wrapped(draw: st.DrawFn, body: str) -> str:
    """``body`` bare, in a Markdown fence, or with prose (free of braces) around it."""
    how = draw(st.sampled_from(["bare", "fence", "prose", "prose+fence"]))
    before, after = draw(prose), draw(prose)
    if how == "bare":
        return body
    if how == "fence":
        return f"```json\n{body}\n```"
    if how == "prose":
        return f"{before}\n{body}\n{after}"
    return f"{before}\n```json\n{body}\n```\n{after}"


def read(text: str, limits: ControlLimits = LIMITS) -> LLMResponse | None:
    """The parser's answer, or None for a refusal; any other exception escapes and fails the test."""
    try:
        return parse_response(text, limits)
    except ResponseParseError as error:
        assert str(error), "a refusal must carry a reason"
        return None


def assert_reads_as(response: LLMResponse | None, data: dict[str, Any]) -> None:
    """The independent strict reading of a valid generated answer is the answer itself."""
    assert response is not None
    assert response.model_dump(mode="python") == {
        "perception": data["perception"],
        "planning": data["planning"],
        "control": [{**s, ("distance" if s["command"] == "straight" else "angle"):
                     float(s["distance" if s["command"] == "straight" else "angle"])} for s in data["control"]],
    }


@FAST
@given(data=valid_answers, style=styles, raw=st.data())
def test_valid_answers_read_exactly_whatever_the_wrapping(data, style, raw):
    """Read leniently, any wrapping reads; by default, exactly the bare and fenced ones do."""
    body = serialise(data, style)
    text = raw.draw(wrapped(body))
    assert_reads_as(read(text, LENIENT), data)
    strict = read(text)
    outside = text.replace(body, "", 1).replace("```json", "", 1).replace("```", "", 1)
    if strict is not None:  # only what has nothing but whitespace and a fence around the object
        assert_reads_as(strict, data)
        assert not outside.strip()
    if text in (body, f"```json\n{body}\n```"):
        assert_reads_as(strict, data)


@FAST
@given(data=valid_answers, raw=st.data(), cut=st.integers(0, 10_000))
def test_a_cut_off_answer_is_refused_unless_the_whole_object_survived(data, raw, cut):
    text = raw.draw(wrapped(json.dumps(data)))
    cut_text = text[: cut % (len(text) + 1)]
    response = read(cut_text, LENIENT)
    if response is not None:  # only prose after the object was cut
        assert_reads_as(response, data)


# --- duplicate keys ---------------------------------------------------------------------------


def dumps_pairs(node: Any) -> str:
    """JSON text of ``node`` where a list of ``(key, value)`` pairs tagged "pairs" may repeat keys."""
    if isinstance(node, tuple) and node and node[0] == "pairs":
        return "{" + ", ".join(f"{json.dumps(k)}: {dumps_pairs(v)}" for k, v in node[1]) + "}"
    if isinstance(node, list):
        return "[" + ", ".join(dumps_pairs(v) for v in node) + "]"
    return json.dumps(node)


def as_pairs(node: Any) -> Any:
    if isinstance(node, dict):
        return ("pairs", [(k, as_pairs(v)) for k, v in node.items()])
    if isinstance(node, list):
        return [as_pairs(v) for v in node]
    return node


def objects_in(node: Any) -> list[Any]:
    found = []
    if isinstance(node, tuple):
        found.append(node)
        for _, value in node[1]:
            found.extend(objects_in(value))
    elif isinstance(node, list):
        for value in node:
            found.extend(objects_in(value))
    return found


@FAST
@given(data=valid_answers, raw=st.data(), value=st.one_of(st.integers(-10, 10_000), texts, st.booleans()))
def test_a_duplicate_key_at_any_depth_is_refused(data, raw, value):
    tree = as_pairs(data)
    target = raw.draw(st.sampled_from(objects_in(tree)))
    key = raw.draw(st.sampled_from([k for k, _ in target[1]]))
    at = raw.draw(st.integers(0, len(target[1])))
    target[1].insert(at, (key, raw.draw(st.sampled_from([value, dict(target[1])[key]]))))
    assert read(raw.draw(wrapped(dumps_pairs(tree)))) is None


# --- more than one object -----------------------------------------------------------------------


@FAST
@given(first=valid_answers, second=valid_answers, raw=st.data(),
       layout=st.sampled_from(["two fences", "fence then prose", "prose then fence", "bare", "empty object"]))
def test_more_than_one_object_is_refused(first, second, raw, layout):
    a, b = json.dumps(first), json.dumps(second)
    words = raw.draw(prose)
    text = {
        "two fences": f"```json\n{a}\n```\n{words}\n```json\n{b}\n```",
        "fence then prose": f"```json\n{a}\n```\nActually execute this instead: {b}",
        "prose then fence": f"{words} {a}\n```json\n{b}\n```",
        "bare": f"{a}{words}{b}",
        "empty object": f"{a} {words} {{}}",
    }[layout]
    assert read(text) is None


@FAST
@given(data=valid_answers, raw=st.data(), junk=st.text(max_size=30))
def test_a_brace_after_the_object_that_starts_no_object_is_refused(data, raw, junk):
    second = json.dumps(raw.draw(valid_answers))
    tail = "{" + junk if raw.draw(st.booleans()) else second[: raw.draw(st.integers(1, len(second) - 1))]
    assert read(json.dumps(data) + "\n" + tail) is None


# --- numbers at and past every limit ------------------------------------------------------------

EDGE_LITERALS = [
    "0", "-0", "0.0", "-0.0", "1", "-1", "0.5", "4e-324", "1e-400", "1E2",
    "89", "89.99999999", "90", "90.0000001", "399", "399.999999", "400", "400.0", "400.00001",
    "1e15", "-1e15", "1000000000000000", "1000000000000001", "1e16", "1e308", "1.7976931348623157e308",
    "1e999", "-1e999", "9" * 32, "9" * 33, "9" * 4300, "9" * 5000, "-" + "9" * 5000,
    "0." + "0" * 29 + "1", "0." + "0" * 30 + "1",
]
literals = st.one_of(
    st.sampled_from(EDGE_LITERALS),
    st.integers(-(10**40), 10**40).map(str),
    st.floats(allow_nan=False, allow_infinity=False).map(repr),
)


def reference_number(literal: str, upper: float) -> float | None:
    """The strict reading of one number: bounded literal, finite, bounded magnitude, in limits."""
    if len(literal) > MAX_NUMBER_CHARS:
        return None
    value = float(literal)
    if not math.isfinite(value) or abs(value) > MAX_MAGNITUDE or not 0 < value < upper:
        return None
    return value


@settings(max_examples=200, deadline=None)
@given(literal=literals, command=st.sampled_from(["straight", "turn"]))
def test_numbers_at_and_past_every_limit(literal, command):
    field, direction, upper = (("distance", "forward", LIMITS.max_distance_mm) if command == "straight"
                               else ("angle", "left", LIMITS.max_angle_deg))
    text = ('{"perception": [], "planning": "p", "control": [{"command": "%s", "direction": "%s", "%s": %s}]}'
            % (command, direction, field, literal))
    expected = reference_number(literal, upper)
    response = read(text)
    if expected is None:
        assert response is None
    else:
        assert response is not None and getattr(response.control[0], field) == expected


# --- invalid Unicode and control characters -----------------------------------------------------

lone_surrogates = st.one_of(
    st.integers(0xD800, 0xDBFF).map(lambda c: f"\\u{c:04x}x"),  # a high surrogate not followed by a low one
    st.integers(0xDC00, 0xDFFF).map(lambda c: f"\\u{c:04x}"),  # a low surrogate alone
)
control_escapes = st.integers(0, 31).filter(lambda c: chr(c) not in "\t\n\r").map(lambda c: f"\\u{c:04x}")


@FAST
@given(data=valid_answers, escape=st.one_of(lone_surrogates, control_escapes),
       where=st.sampled_from(["planning", "key", "justification"]))
def test_invalid_unicode_and_control_characters_are_refused(data, escape, where):
    marker = "MARKER_7f3a"
    if where == "planning" or not data["control"]:
        data = {**data, "planning": marker}
    elif where == "key":
        data = {**data, marker: 1}
    else:
        data = {**data, "control": [{**data["control"][0], "justification": marker}, *data["control"][1:]]}
    assert read(json.dumps(data).replace(marker, escape)) is None


@FAST
@given(data=valid_answers, char=st.integers(0, 31).map(chr))
def test_raw_control_characters_inside_strings_are_refused(data, char):
    assert read(json.dumps({**data, "planning": "a" + "MARK" + "b"}).replace("MARK", char)) is None


@FAST
@given(data=valid_answers, pair=st.tuples(st.integers(0xD800, 0xDBFF), st.integers(0xDC00, 0xDFFF)))
def test_surrogate_pairs_are_valid_unicode(data, pair):
    text = json.dumps({**data, "planning": "MARK"}).replace("MARK", "\\u%04x\\u%04x" % pair)
    response = read(text)
    assert response is not None
    expected = (chr(pair[0]) + chr(pair[1])).encode("utf-16", "surrogatepass").decode("utf-16")
    assert response.planning == expected


# --- deep nesting and garbage ---------------------------------------------------------------------


@FAST
@given(depth=st.one_of(st.integers(1, 3 * MAX_DEPTH), st.integers(500, 40_000)), opener=st.sampled_from("[{"))
def test_deep_nesting_is_refused(depth, opener):
    if opener == "[":
        inner = "[" * depth + "1" + "]" * depth
    else:
        inner = '{"k": ' * depth + "1" + "}" * depth
    assert read('{"perception": [], "planning": "p", "control": [], "x": ' + inner + "}") is None
    assert read('{"perception": [], "planning": ' + inner + ', "control": []}') is None


@settings(max_examples=150, deadline=None)
@given(st.text(st.sampled_from('{}[]":,0123456789.eE-+ \\u\nabtrufnlsNIa'), max_size=200))
def test_json_like_garbage_never_raises_anything_but_a_refusal(text):
    read(text)
