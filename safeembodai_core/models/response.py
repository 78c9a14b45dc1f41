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

The schema is the contract; the one strict reading of a whole reply (envelope, choices,
reasoning, finish reason, the text around the object) is :mod:`safeembodai_core.models.reply`.
Schema errors are described with every LLM-written key, tag and value quoted as a short JSON string
literal (:func:`safeembodai_core.trust.quoting.quote_untrusted`), never repeated bare.
"""

from __future__ import annotations

import functools
import json
import math
from typing import Any, Literal, cast, get_args

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..trust.quoting import quote_untrusted
from .control import DEFAULT_LIMITS, MAX_TEXT, ControlLimits, ControlSignal, Straight, Turn
from .strict_json import QUOTE_CHARS, ResponseParseError

__all__ = ["LLMResponse", "PerceptionEntry", "ResponseParseError", "describe_schema_error", "response_json_schema",
           "schema_outline"]


class PerceptionEntry(BaseModel):
    """What the LLM perceived in one input, and whether it judges that input an attack."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    input: str = Field(max_length=64, description="human_instruction, camera_image, lidar_image, ...")
    result: str = Field(max_length=MAX_TEXT)
    is_attack: bool = Field(strict=True, description="required: an answer that does not say is refused")


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


def response_json_schema() -> dict[str, Any]:
    """JSON schema of :class:`LLMResponse`, rendered into the prompt's response format ``f``."""
    return LLMResponse.model_json_schema()


_SCHEMA_NAMES = frozenset(
    {name for model in (LLMResponse, PerceptionEntry, Straight, Turn) for name in model.model_fields}
    | {tag for model in (Straight, Turn) for tag in get_args(model.model_fields["command"].annotation)}
)
# pydantic messages that are built from the schema only, never from the input.
_SCHEMA_ONLY_MESSAGES = frozenset({
    "missing", "extra_forbidden", "string_type", "string_too_long", "bool_type", "bool_parsing",
    "float_type", "float_parsing", "int_type", "greater_than", "greater_than_equal", "less_than",
    "less_than_equal", "finite_number", "literal_error", "union_tag_not_found", "model_type",
    "model_attributes_type", "dict_type", "list_type", "too_long", "too_short", "value_error",
})
_SCALARS = (str, int, float, bool, type(None))


def _location(parts: tuple[Any, ...]) -> str:
    """``control.0.straight.distance``; a key the schema does not know is quoted: it is the LLM's."""
    rendered = [str(p) if isinstance(p, int) or p in _SCHEMA_NAMES else quote_untrusted(p, QUOTE_CHARS)
                for p in parts]
    return ".".join(rendered) or "(top level)"


def _message(item: Any) -> str:
    kind = item.get("type", "")
    if kind == "union_tag_invalid":  # pydantic's message repeats the LLM's tag unquoted
        ctx = item.get("ctx") or {}
        return (f"{ctx.get('discriminator', 'command')} must be one of {ctx.get('expected_tags', '')}, "
                f"got {quote_untrusted(ctx.get('tag', ''), QUOTE_CHARS)}")
    message = item["msg"] if kind in _SCHEMA_ONLY_MESSAGES else f"invalid value ({kind})"
    value = item.get("input")
    if kind not in ("missing", "value_error") and isinstance(value, _SCALARS):
        shown = quote_untrusted(value, QUOTE_CHARS) if isinstance(value, str) else json.dumps(value)
        message += f" (got {shown})"
    return message


def describe_schema_error(error: ValidationError, most: int = 6) -> str:
    """The first ``most`` problems of ``error``, with every LLM-written fragment quoted."""
    parts = [f"{_location(tuple(item['loc']))}: {_message(item)}" for item in error.errors()[:most]]
    more = error.error_count() - len(parts)
    return "; ".join(parts) + (f"; and {more} more" if more > 0 else "")


#: How the response outline shows a distance and an angle (:func:`schema_outline`).
OutlineExamples = Literal["half", "varied", "seeded", "zero"]
OUTLINE_EXAMPLES: tuple[str, ...] = get_args(OutlineExamples)
#: The fractions of the limit the ``varied`` outline shows, in the order of its four signals.
VARIED_FRACTIONS = {"turn": (0.22, 0.78), "straight": (0.3, 0.8)}


def _inside(limit: float, fraction: float) -> int | float:
    """``fraction`` of ``limit``: a whole number when one lies inside (0, limit), else 3 decimals."""
    value = limit * fraction
    whole = int(value)
    return whole if 1 <= whole < limit else round(value, 3)


def _drawn(limit: float, rng: np.random.Generator) -> int | float:
    """A value drawn uniformly inside (0, limit): a whole number when there is one."""
    top = math.ceil(limit) - 1
    if top >= 1:
        return int(rng.integers(1, top + 1))
    return round(float(rng.uniform(0.05, 0.95)) * limit, 3)


@functools.lru_cache(maxsize=1)
def _response_schema() -> dict[str, Any]:
    """:class:`LLMResponse`'s JSON schema, made once (pydantic takes milliseconds per call; every
    prompt's outline reads it, never writes it)."""
    return LLMResponse.model_json_schema()


def schema_outline(limits: ControlLimits = DEFAULT_LIMITS, examples: OutlineExamples = "half",
                   rng: np.random.Generator | None = None) -> str:
    """A compact JSON outline of the response schema, generated from :class:`LLMResponse`.

    Prompts carry this instead of the full JSON schema (fewer tokens); being generated from the
    model, it cannot drift from what :func:`parse_response` accepts. Numbers are shown as JSON
    numbers, never as quoted text (``"distance": "number (millimetres)"`` invited strings). How
    a distance and an angle are shown, ``examples``:

    * ``half``: half the limit (200 mm, 45 degrees by default), one straight and one turn;
    * ``varied``: four signals, turn / straight / turn / straight, at the
      :data:`VARIED_FRACTIONS` of the limits (20, 120, 70, 320 by default);
    * ``seeded``: one straight and one turn with values drawn from ``rng`` inside the limits
      (the prompt builder seeds it from the step's own inputs, so a prompt is reproducible);
    * ``zero``: 0 for both, outside the contract (0 < value < limit, stated in words by the
      prompt's Methods line): a copied 0 is refused.

    Every other number is shown as 0. Shown values other than ``zero`` lie inside ``limits``,
    so a model that copies the outline still writes a valid value.
    """
    if examples not in OUTLINE_EXAMPLES:
        raise ValueError(f"examples must be one of {', '.join(OUTLINE_EXAMPLES)}, got {examples!r}")
    if examples == "seeded" and rng is None:
        raise ValueError("the seeded outline needs an rng")
    schema = _response_schema()
    defs = schema.get("$defs", {})
    limit_of = {"distance": limits.max_distance_mm, "angle": limits.max_angle_deg}
    command_of = {"distance": "straight", "angle": "turn"}
    shown: dict[str, int] = {"distance": 0, "angle": 0}  # how many of each the outline has shown so far

    def number(name: str) -> int | float:
        limit = limit_of.get(name)
        if limit is None or examples == "zero":
            return 0
        if examples == "seeded":
            assert rng is not None  # refused above
            return _drawn(limit, rng)
        if examples == "varied":
            fractions = VARIED_FRACTIONS[command_of[name]]
            value = _inside(limit, fractions[shown[name] % len(fractions)])
            shown[name] += 1
            return value
        return _inside(limit, 0.5)

    def outline(node: dict[str, Any]) -> Any:
        if "$ref" in node:
            return outline(defs[node["$ref"].rsplit("/", 1)[-1]])
        if "const" in node:
            return node["const"]
        if "enum" in node:
            return "|".join(str(v) for v in node["enum"])
        if "oneOf" in node or "anyOf" in node:
            options = cast("list[dict[str, Any]]", node.get("oneOf") or node.get("anyOf"))  # one is there
            if examples == "varied":  # turn, straight, turn, straight
                turn, straight = sorted(options, key=lambda option: "Turn" not in option.get("$ref", ""))
                return [outline(turn), outline(straight), outline(turn), outline(straight)]
            return [outline(option) for option in options]
        kind: Any = node.get("type")  # the schema's JSON, as written
        if kind == "object":
            return {name: number(name) if sub.get("type") in ("number", "integer") else outline(sub)
                    for name, sub in node.get("properties", {}).items()}
        if kind == "array":
            inner = outline(node.get("items", {}))
            return inner if isinstance(inner, list) else [inner]
        if kind in ("number", "integer"):
            return 0
        if kind == "boolean":
            return node.get("default", False)
        return {"string": "text"}.get(kind, "value")

    return json.dumps(outline(schema), separators=(",", ":"))
