"""Reading the one JSON object of an LLM answer, strictly.

An LLM answer is untrusted text. Python's ``json`` module is lenient in ways that let one
answer mean two things, or crash the reader, so :func:`read_one_object` refuses, with a
:class:`ResponseParseError` whose message is written for the LLM to read on a retry:

* **a duplicate key at any depth** -- ``json`` keeps the last value, so ``"distance": 5000,
  "distance": 100`` would show a reviewer one number and run another;
* **more than one JSON object**, fenced or not, and any ``{`` outside the one object that does not
  start a complete object (a cut-off second plan is still a second plan);
* **numbers that are not plain, bounded numbers**: ``NaN``/``Infinity``, literals longer than
  :data:`MAX_NUMBER_CHARS` (Python refuses to convert integers past 4,300 digits with a
  ``ValueError``), and magnitudes above :data:`MAX_MAGNITUDE` (``1e999`` decodes to infinity);
* **text that is not valid Unicode**: lone surrogates, raw or written as ``\\ud800`` escapes
  (they cannot be encoded, stored or logged), and C0 control characters other than tab, line
  feed and carriage return inside strings;
* **nesting deeper than** :data:`MAX_DEPTH` (the answer schema needs three levels).

Objects nested inside the one top-level object are of course part of it. Fences and prose
around the object are ignored, so a Markdown fence is fine as long as it holds the only object.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

from ..trust.quoting import quote_untrusted

MAX_NUMBER_CHARS = 32
MAX_MAGNITUDE = 1e15
MAX_DEPTH = 10
QUOTE_CHARS = 60  # how much of an LLM-written fragment a refusal reason quotes
_BAD_CONTROL = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f]")
_SURROGATE = re.compile("[\ud800-\udfff]")
_JSON_WHITESPACE = " \t\n\r"  # what JSON calls whitespace: no-break spaces and the like are not


class ResponseParseError(ValueError):
    """The LLM's text is not a valid answer; ``str(error)`` is written for the LLM to read."""


def _object_without_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    seen: set[str] = set()
    for key, _ in pairs:
        if key in seen:
            raise ResponseParseError(
                f"key {quote_untrusted(key, QUOTE_CHARS)} appears more than once in one JSON object; "
                "each key may appear only once"
            )
        seen.add(key)
    return dict(pairs)


def _bounded(value: float, literal: str) -> float:
    if not math.isfinite(value) or abs(value) > MAX_MAGNITUDE:
        raise ResponseParseError(
            f"number {quote_untrusted(literal, QUOTE_CHARS)} is too large: use finite numbers "
            f"within ±{MAX_MAGNITUDE:g}"
        )
    return value


def _too_long(literal: str) -> ResponseParseError:
    return ResponseParseError(
        f"number {quote_untrusted(literal, 20)} has {len(literal)} characters; at most "
        f"{MAX_NUMBER_CHARS} are allowed"
    )


def _read_int(literal: str) -> int:
    if len(literal) > MAX_NUMBER_CHARS:  # checked before int(): Python itself stops at 4,300 digits
        raise _too_long(literal)
    value = int(literal)
    _bounded(float(value), literal)
    return value


def _read_float(literal: str) -> float:
    if len(literal) > MAX_NUMBER_CHARS:
        raise _too_long(literal)
    return _bounded(float(literal), literal)


def _reject_constant(name: str) -> Any:
    raise ResponseParseError(f"JSON constant {name} is not allowed; use finite numbers")


def _strict_decoder() -> json.JSONDecoder:
    # A fresh decoder per answer: the C scanner keeps per-call state, and hooks run Python code.
    return json.JSONDecoder(
        object_pairs_hook=_object_without_duplicates,
        parse_int=_read_int,
        parse_float=_read_float,
        parse_constant=_reject_constant,
        strict=True,  # raw control characters inside strings are a decode error
    )


def _check_text(text: str, where: str) -> None:
    surrogate = _SURROGATE.search(text)
    if surrogate:
        raise ResponseParseError(
            f"{where} is not valid Unicode: lone surrogate U+{ord(surrogate.group()):04X}; "
            "write characters, not surrogate escapes"
        )
    control = _BAD_CONTROL.search(text)
    if control:
        raise ResponseParseError(
            f"{where} contains the control character U+{ord(control.group()):04X}; "
            "only tab, line feed and carriage return are allowed"
        )


def _check_tree(value: Any) -> None:
    """Depth and string content of a decoded object, without recursion."""
    stack: list[tuple[Any, int]] = [(value, 1)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, (dict, list)) and depth > MAX_DEPTH:
            raise ResponseParseError(f"answer nests JSON too deeply (more than {MAX_DEPTH} levels)")
        if isinstance(node, dict):
            for key, item in node.items():
                _check_text(key, "a key of the answer")
                stack.append((item, depth + 1))
        elif isinstance(node, list):
            stack.extend((item, depth + 1) for item in node)
        elif isinstance(node, str):
            _check_text(node, "a string of the answer")


def find_objects(text: str, *, most: int | None = None) -> list[tuple[dict[str, Any], int, int]]:
    """Every complete JSON object in ``text`` with its span, strictly; a ``{`` that starts none is refused.

    With ``most``, at most that many objects are read; one more raises (the caller's limit).
    """
    if _SURROGATE.search(text):
        _check_text(text, "the answer")
    decoder = _strict_decoder()
    found: list[tuple[dict[str, Any], int, int]] = []
    start = text.find("{")
    while start != -1:
        try:
            value, end = decoder.raw_decode(text, start)
        except json.JSONDecodeError as error:
            where = "after the JSON object, " if found else ""
            raise ResponseParseError(
                f"answer is not valid JSON: {where}the {{ at char {start} does not start a complete "
                f"object ({error.msg} at char {error.pos}); send exactly one complete JSON object"
            ) from None
        except RecursionError:
            raise ResponseParseError("answer nests JSON too deeply to be read") from None
        found.append((value, start, end))
        if most is not None and len(found) > most:
            break
        start = text.find("{", end)
    return found


def read_sole_object(text: str) -> tuple[dict[str, Any], int, int]:
    """The only JSON object in ``text`` and its span ``[start, end)``, read strictly."""
    found = find_objects(text)
    if not found:
        raise ResponseParseError("answer contains no JSON object")
    if len(found) > 1:
        raise ResponseParseError(
            f"answer contains {len(found)} JSON objects; send exactly one (two plans are ambiguous, "
            "so none is executed)"
        )
    value, start, end = found[0]
    _check_tree(value)
    return value, start, end


def read_one_object(text: str) -> dict[str, Any]:
    """The only JSON object in ``text`` (bare, fenced, or surrounded by prose), read strictly."""
    return read_sole_object(text)[0]


def read_json_document(text: str, what: str = "the document") -> Any:
    """A whole JSON document (one value, nothing but JSON whitespace around it) read as strictly
    as an answer's object: duplicate keys, non-finite or huge numbers, bad Unicode and deep nesting
    are refused with a :class:`ResponseParseError` naming ``what``. For JSON that came from an LLM by
    another road (a recorded plan in a bag), so that it gets the answer's reading, not a second one."""
    if _SURROGATE.search(text):
        _check_text(text, what)
    start = len(text) - len(text.lstrip(_JSON_WHITESPACE))
    try:
        value, end = _strict_decoder().raw_decode(text, start)
    except json.JSONDecodeError as error:
        raise ResponseParseError(f"{what} is not valid JSON ({error.msg} at char {error.pos})") from None
    except RecursionError:
        raise ResponseParseError(f"{what} nests JSON too deeply to be read") from None
    if text[end:].strip(_JSON_WHITESPACE):
        raise ResponseParseError(f"{what} holds more than one JSON value (text after char {end})")
    _check_tree(value)
    return value
