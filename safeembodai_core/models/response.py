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

:func:`parse_response` is the one strict reading of an answer, shared by Algorithm 1
(:mod:`safeembodai_core.loop.guarded_step`) and :meth:`safeembodai_core.api.Guard.check_answer`.
It accepts the object bare, inside a Markdown code fence or with prose around it, and refuses
everything else with a :class:`ResponseParseError` whose message is fed back to the LLM on a
retry:

* an answer the provider did not end normally (``finish_reason`` outside
  :data:`NORMAL_FINISH_REASONS`: cut off at the token limit, filtered, ...);
* an answer longer than :data:`MAX_RESPONSE_CHARS`;
* what :func:`~safeembodai_core.models.strict_json.read_one_object` refuses: duplicate keys,
  more than one object (or a stray ``{``), truncated JSON, NaN/Infinity, huge numbers, invalid
  Unicode, control characters, deep nesting;
* what the schema refuses: unknown keys, missing keys, wrong types, out-of-limit values, more
  signals than the limits allow, oversized text.

Reasons never repeat LLM-written text bare: keys, tags and values are quoted as short JSON
string literals (:func:`safeembodai_core.quoting.quote_untrusted`). Nothing else ever escapes:
an unexpected exception while reading is turned into a refusal too, so no answer can end a trial.
See "The parsing contract" in ``docs/defences.md``.
"""

from __future__ import annotations

import json
import math
from typing import Any, Literal, get_args

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..logs import get_logger
from ..quoting import CLIPPED, quote_untrusted
from .control import DEFAULT_LIMITS, MAX_TEXT, ControlLimits, ControlSignal, Straight, Turn
from .strict_json import QUOTE_CHARS, ResponseParseError, read_one_object

log = get_logger(__name__)

MAX_RESPONSE_CHARS = 64_000
MAX_FINISH_REASON_CHARS = 64

# Finish reasons that mean "the model ended its answer itself". OpenAI (and litellm, which maps
# every provider to OpenAI's names) says "stop"; the others are the native names of providers
# reached without litellm: Anthropic "end_turn"/"stop_sequence", Hugging Face "eos"/"eos_token",
# Cohere "COMPLETE" (compared case-insensitively). Everything else -- "length", "content_filter",
# "tool_calls", "error", ... -- is refused. None means the backend does not report a reason and is
# accepted: the strict parser still refuses a cut-off object. litellm maps reasons it does not
# know (and some errors) to "stop"; the built-in litellm backend reports the provider's own
# reason instead (plugins/backends/litellm_reply.py), which is then refused here.
NORMAL_FINISH_REASONS = frozenset({"stop", "end_turn", "stop_sequence", "eos", "eos_token", "complete"})


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


def finish_reason_text(reason: Any) -> str | None:
    """A backend's finish reason as short text (an enum's value, say); None when not reported."""
    if reason is None:
        return None
    text = str(getattr(reason, "value", reason))
    # clipped visibly: padding cannot push an abnormal reason past the cut and leave "stop" in front
    return text if len(text) <= MAX_FINISH_REASON_CHARS else text[:MAX_FINISH_REASON_CHARS] + CLIPPED


def _check_finish_reason(reason: str | None) -> None:
    if reason is None or reason.strip().lower() in NORMAL_FINISH_REASONS:
        return
    if reason.strip().lower() in ("length", "max_tokens"):
        hint = "it was cut off at the token limit; send one complete, shorter JSON object"
    else:
        hint = "the provider stopped it before a normal end; send one complete JSON object"
    raise ResponseParseError(
        f"answer ended with finish reason {quote_untrusted(reason, QUOTE_CHARS)}, not a normal stop, "
        f"so it is not executed: {hint}"
    )


def extract_json(text: str) -> Any:
    """Find exactly one JSON object in ``text`` (bare, fenced, or surrounded by prose), strictly."""
    if len(text) > MAX_RESPONSE_CHARS:
        raise ResponseParseError(f"answer is {len(text)} characters long; the limit is {MAX_RESPONSE_CHARS}")
    return read_one_object(text)


def _parse(text: Any, limits: ControlLimits, finish_reason: Any) -> LLMResponse:
    _check_finish_reason(finish_reason_text(finish_reason))
    if not isinstance(text, str):
        raise ResponseParseError(f"answer is not text (got {type(text).__name__})")
    data = extract_json(text)
    try:
        response = LLMResponse.model_validate(data, context={"limits": limits})
    except ValidationError as error:
        raise ResponseParseError(
            f"answer does not follow the response schema: {describe_schema_error(error)}"
        ) from None
    if len(response.control) > limits.max_signals:
        raise ResponseParseError(
            f"answer has {len(response.control)} control signals; at most {limits.max_signals} are allowed"
        )
    return response


def parse_response(text: str, limits: ControlLimits = DEFAULT_LIMITS, *, finish_reason: Any = None) -> LLMResponse:
    """Parse and validate an LLM answer; raise :class:`ResponseParseError` on anything invalid.

    ``finish_reason`` is the backend's reason the answer ended (None: not reported). This never
    raises anything but :class:`ResponseParseError`.
    """
    try:
        return _parse(text, limits, finish_reason)
    except ResponseParseError:
        raise
    except Exception as error:  # any other failure to read untrusted text is a refusal, not a crash
        # quoted: the message may hold LLM text, lone surrogates included, that a log cannot encode
        log.warning("answer.unreadable", error=type(error).__name__, detail=quote_untrusted(error, 200))
        raise ResponseParseError(
            f"answer could not be read ({type(error).__name__}); send exactly one valid JSON object"
        ) from None


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
    schema = LLMResponse.model_json_schema()
    defs = schema.get("$defs", {})
    limit_of = {"distance": limits.max_distance_mm, "angle": limits.max_angle_deg}
    command_of = {"distance": "straight", "angle": "turn"}
    shown: dict[str, int] = {"distance": 0, "angle": 0}  # how many of each the outline has shown so far

    def number(name: str) -> int | float:
        limit = limit_of.get(name)
        if limit is None or examples == "zero":
            return 0
        if examples == "seeded":
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
            options = node.get("oneOf") or node.get("anyOf")
            if examples == "varied":  # turn, straight, turn, straight
                turn, straight = sorted(options, key=lambda option: "Turn" not in option.get("$ref", ""))
                return [outline(turn), outline(straight), outline(turn), outline(straight)]
            return [outline(option) for option in options]
        kind = node.get("type")
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
