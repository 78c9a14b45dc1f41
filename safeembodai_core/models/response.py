"""The LLM's answer (Table II of the paper) and the parser that treats it as untrusted input.

The answer is one JSON object::

    {
      "perception": [
        {"input": "human_instruction", "result": "...", "is_attack": false},
        {"input": "camera_image", "result": "...", "is_attack": false},
        {"input": "lidar_image", "result": "...", "is_attack": false}
      ],
      "planning": "why these control signals",
      "control": [
        {"command": "turn", "direction": "left", "angle": 30, "justification": "..."},
        {"command": "straight", "direction": "forward", "distance": 250, "justification": "..."}
      ]
    }

:func:`parse_response` accepts the object bare, inside a Markdown code fence or with prose
around it, and rejects everything else with a :class:`ResponseParseError` whose message is fed
back to the LLM on a retry: more than one object, truncated JSON, NaN/Infinity, unknown keys,
missing keys, out-of-limit values, more signals than allowed, oversized text.
"""

from __future__ import annotations

import json
import re
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from .control import DEFAULT_LIMITS, MAX_TEXT, ControlLimits, ControlSignal

MAX_RESPONSE_CHARS = 64_000
_FENCE = re.compile(r"```(?:json|JSON)?\s*(.*?)```", re.DOTALL)


class PerceptionEntry(BaseModel):
    """What the LLM perceived in one input, and whether it judges that input an attack."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    input: str = Field(max_length=64, description="human_instruction, camera_image, lidar_image, ...")
    result: str = Field(max_length=MAX_TEXT)
    is_attack: bool = Field(False, strict=True)


class LLMResponse(BaseModel):
    """A parsed, schema-valid answer: perception per input, a plan, and control signals."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    perception: list[PerceptionEntry] = Field(max_length=16)
    planning: str = Field(max_length=MAX_TEXT)
    control: list[ControlSignal]

    @property
    def flags_attack(self) -> bool:
        """True when any perception entry is flagged as an attack (the paper's ADR numerator)."""
        return any(entry.is_attack for entry in self.perception)


class ResponseParseError(ValueError):
    """The LLM's text is not a valid answer; ``str(error)`` is written for the LLM to read."""


def response_json_schema() -> dict[str, Any]:
    """JSON schema of :class:`LLMResponse`, rendered into the prompt's response format ``f``."""
    return LLMResponse.model_json_schema()


def _reject_constant(name: str) -> Any:
    raise ResponseParseError(f"JSON constant {name} is not allowed; use finite numbers")


def _decode_objects(text: str) -> list[Any]:
    decoder = json.JSONDecoder(parse_constant=_reject_constant)
    found: list[Any] = []
    index = text.find("{")
    last_error: json.JSONDecodeError | None = None
    while index != -1:
        try:
            value, end = decoder.raw_decode(text, index)
        except json.JSONDecodeError as error:
            last_error = error
            index = text.find("{", index + 1)
            continue
        except RecursionError:
            raise ResponseParseError("answer nests JSON too deeply") from None
        found.append(value)
        index = text.find("{", end)
    if not found and last_error is not None:
        raise ResponseParseError(f"answer is not valid JSON ({last_error.msg} at char {last_error.pos})")
    return found


def extract_json(text: str) -> Any:
    """Find exactly one JSON object in ``text`` (bare, fenced, or surrounded by prose)."""
    if len(text) > MAX_RESPONSE_CHARS:
        raise ResponseParseError(f"answer is {len(text)} characters long; the limit is {MAX_RESPONSE_CHARS}")
    fenced = _FENCE.findall(text)
    candidates = _decode_objects(fenced[0]) if len(fenced) == 1 else _decode_objects(text)
    objects = [c for c in candidates if isinstance(c, dict)]
    if not objects:
        raise ResponseParseError("answer contains no JSON object")
    if len(objects) > 1:
        raise ResponseParseError(f"answer contains {len(objects)} JSON objects; send exactly one")
    return objects[0]


def _describe(error: ValidationError) -> str:
    parts = []
    for item in error.errors()[:6]:
        where = ".".join(str(p) for p in item["loc"]) or "(top level)"
        parts.append(f"{where}: {item['msg']}")
    more = error.error_count() - len(parts)
    return "; ".join(parts) + (f"; and {more} more" if more > 0 else "")


def parse_response(text: str, limits: ControlLimits = DEFAULT_LIMITS) -> LLMResponse:
    """Parse and validate an LLM answer; raise :class:`ResponseParseError` on anything invalid."""
    data = extract_json(text)
    try:
        response = LLMResponse.model_validate(data, context={"limits": limits})
    except ValidationError as error:
        raise ResponseParseError(f"answer does not follow the response schema: {_describe(error)}") from None
    if len(response.control) > limits.max_signals:
        raise ResponseParseError(
            f"answer has {len(response.control)} control signals; at most {limits.max_signals} are allowed"
        )
    return response


def schema_outline() -> str:
    """A compact JSON outline of the response schema, generated from :class:`LLMResponse`.

    Prompts carry this instead of the full JSON schema (fewer tokens); being generated from the
    model, it cannot drift from what :func:`parse_response` accepts.
    """
    schema = LLMResponse.model_json_schema()
    defs = schema.get("$defs", {})

    def outline(node: dict[str, Any]) -> Any:
        if "$ref" in node:
            return outline(defs[node["$ref"].rsplit("/", 1)[-1]])
        if "const" in node:
            return node["const"]
        if "enum" in node:
            return "|".join(str(v) for v in node["enum"])
        if "oneOf" in node or "anyOf" in node:
            return [outline(option) for option in node.get("oneOf") or node.get("anyOf")]
        kind = node.get("type")
        if kind == "object":
            return {name: outline(sub) for name, sub in node.get("properties", {}).items()}
        if kind == "array":
            inner = outline(node.get("items", {}))
            return inner if isinstance(inner, list) else [inner]
        if kind == "number":
            return "number (" + str(node.get("description", "")).split(",")[0] + ")" if node.get("description") else "number"
        if kind == "boolean":
            return node.get("default", False)
        return {"string": "text", "integer": "integer"}.get(kind, "value")

    return json.dumps(outline(schema), separators=(",", ":"))
