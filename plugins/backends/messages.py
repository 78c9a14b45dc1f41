"""A :class:`~safeembodai_core.models.Prompt` as OpenAI-style chat messages, and the output format.

Shared by the litellm backends (what is sent) and the mock pilot (what would have been sent,
for token counting). Images become base64 ``data:`` URLs -- never http(s) URLs, which
litellm's token counter would try to download. Models without a system role (Gemma) get the
system prompt folded into the start of the user turn.
"""

from __future__ import annotations

import base64
import copy
import json
import math
from functools import lru_cache
from typing import Any, Literal

import structlog

from safeembodai_core.models import ImagePart, Prompt, TextPart
from safeembodai_core.models.control import DEFAULT_LIMITS, ControlLimits
from safeembodai_core.models.response import response_json_schema

from .json_modes import DEFAULT_MAX_TOKENS, LEGACY_JSON_MODES, ImageDetail, JsonMode  # noqa: F401  (re-exported)

Bounds = Literal["range", "enum"]
MAX_ENUM_VALUES = 400
_DROP_KEYS = ("title", "description", "maxLength", "default")

log = structlog.get_logger(__name__)

#: The longest text field the decoding schema asks for. llama-cpp-python 0.3.x writes a
#: ``maxLength`` of n as n nested optional groups; its server parses a cap of 1,000 but fails to
#: parse one of 1,500 or 2,000 (the contract's own cap) and the server process exits.
MAX_GRAMMAR_TEXT = 1000
#: The shortest cap a text field gets, however small ``max_tokens`` is (then the bound may not hold).
MIN_GRAMMAR_TEXT = 16
#: Cap of a perception entry's ``input`` (an input's name: ``human_instruction``, ``lidar_image``).
INPUT_NAME_CHARS = 32
#: How the free-text budget is shared: weight per occurrence of each text field.
TEXT_SHARES = {"planning": 4, "result": 2, "justification": 1}


def data_url(image: ImagePart) -> str:
    return f"data:{image.media_type};base64,{base64.b64encode(image.data).decode('ascii')}"


def chat_messages(prompt: Prompt, *, detail: ImageDetail = "low", send_images: bool = True,
                  fold_system: bool = False) -> list[dict[str, Any]]:
    """The system message Y and the user message I_i (text parts, then image parts)."""
    content: list[dict[str, Any]] = []
    if fold_system and prompt.system:
        content.append({"type": "text", "text": prompt.system})
    for part in prompt.user:
        if isinstance(part, TextPart):
            content.append({"type": "text", "text": part.text})
        elif isinstance(part, ImagePart) and send_images:
            content.append({"type": "image_url", "image_url": {"url": data_url(part), "detail": detail}})
    if all(item["type"] == "text" for item in content):
        # plain string content: text-only servers (llama.cpp, older vLLM) accept nothing else
        user: Any = "\n\n".join(item["text"] for item in content)
    else:
        user = content
    messages: list[dict[str, Any]] = []
    if prompt.system and not fold_system:
        messages.append({"role": "system", "content": prompt.system})
    messages.append({"role": "user", "content": user})
    return messages


def carries_images(messages: list[dict[str, Any]]) -> bool:
    """Whether any of the chat ``messages`` holds an image part."""
    return any(isinstance(message.get("content"), list)
               and any(isinstance(part, dict) and part.get("type") == "image_url" for part in message["content"])
               for message in messages if isinstance(message, dict))


def _whole_values(limit: float, most: int = MAX_ENUM_VALUES) -> list[int]:
    """The whole numbers v with 0 < v < ``limit``, every n-th one when there are more than ``most``."""
    top = math.ceil(limit) - 1
    step = max(1, math.ceil(top / most))
    return list(range(step, top + 1, step))


def bounded_number(limit: float, bounds: Bounds) -> dict[str, Any]:
    """The decoding schema of a distance or angle that must lie in (0, ``limit``).

    ``range``: a whole number with ``minimum``/``maximum`` (llama.cpp's ``llama-server`` and
    vLLM's guided decoding enforce integer bounds); ``enum``: the list of allowed whole numbers
    (llama-cpp-python 0.3.x drops every bound but honours an ``enum``). With no whole number
    below the limit (a limit of 1 or less), a number with exclusive bounds, which only some
    servers enforce.
    """
    values = _whole_values(limit)
    if not values:
        return {"type": "number", "exclusiveMinimum": 0, "exclusiveMaximum": limit}
    if bounds == "enum":
        return {"type": "integer", "enum": values}
    return {"type": "integer", "minimum": values[0], "maximum": values[-1]}


def _trimmed_schema(limits: ControlLimits, bounds: Bounds, max_perception: int,
                    caps: dict[str, int]) -> dict[str, Any]:
    schema = copy.deepcopy(response_json_schema())
    schema["properties"]["perception"].update(minItems=1, maxItems=max_perception)
    schema["properties"]["control"].update(minItems=1, maxItems=limits.max_signals)
    schema["$defs"]["Straight"]["properties"]["distance"] = bounded_number(limits.max_distance_mm, bounds)
    schema["$defs"]["Turn"]["properties"]["angle"] = bounded_number(limits.max_angle_deg, bounds)

    def trim(node: Any) -> Any:
        if isinstance(node, dict):
            cleaned = {k: trim(v) for k, v in node.items() if k not in _DROP_KEYS}
            if cleaned.get("type") == "object" and "properties" in cleaned:
                cleaned["required"] = list(cleaned["properties"])
            return cleaned
        if isinstance(node, list):
            return [trim(item) for item in node]
        return node

    schema = trim(schema)
    texts = [schema["properties"]["planning"], schema["$defs"]["PerceptionEntry"]["properties"]["result"],
             schema["$defs"]["PerceptionEntry"]["properties"]["input"],
             schema["$defs"]["Straight"]["properties"]["justification"],
             schema["$defs"]["Turn"]["properties"]["justification"]]
    for node, name in zip(texts, ("planning", "result", "input", "justification", "justification")):
        node.update(maxLength=caps[name], pattern=text_pattern(caps[name]))
    return schema


def text_pattern(most: int) -> str:
    """A text field's ``pattern``: at most ``most`` characters, none of them a quote, a backslash
    or a control character.

    llama-cpp-python 0.3.x reads a string's ``pattern`` before its ``maxLength`` and its own
    string rule lets raw control characters through (a raw newline inside a string, which no
    JSON parser accepts: seen from SmolLM2 asked for a long plan); without escapes one character
    of the grammar is one character of the answer. Servers that read ``maxLength`` get the same cap.
    """
    return rf'^[^"\\\x00-\x1f]{{0,{most}}}$'


def longest_answer_chars(schema: dict[str, Any]) -> int:
    """The most characters an answer decoded under ``schema`` can have.

    Counted as llama-cpp-python 0.3.x's grammar writes it: compact JSON with one optional space
    after every brace, bracket, comma, colon, key and value, every property present; a string
    of ``maxLength`` n holds n characters (its :func:`text_pattern` allows no escapes). Raises
    ``ValueError`` for a part with no bound (a string without ``maxLength``, an array without
    ``maxItems``, a number without a largest value).
    """
    defs = schema.get("$defs", {})

    def size(node: dict[str, Any]) -> int:
        if "$ref" in node:
            return size(defs[node["$ref"].rsplit("/", 1)[-1]])
        if "const" in node:
            return len(json.dumps(node["const"])) + 1
        if "enum" in node:
            return max(len(json.dumps(value)) for value in node["enum"]) + 1
        if "oneOf" in node or "anyOf" in node:
            return max(size(option) for option in node.get("oneOf") or node["anyOf"])
        kind = node.get("type")
        if kind == "object":
            props = node.get("properties", {})
            inner = sum(len(json.dumps(key)) + 3 + size(value) for key, value in props.items())
            return 4 + inner + 2 * max(0, len(props) - 1)
        if kind == "array" and "maxItems" in node:
            most = node["maxItems"]
            return 4 + most * size(node.get("items", {})) + 2 * max(0, most - 1)
        if kind == "string" and "maxLength" in node:
            return 3 + node["maxLength"]
        if kind == "boolean":
            return len("false") + 1
        if kind in ("integer", "number") and "maximum" in node:
            return len(json.dumps(node["maximum"])) + (0 if kind == "integer" else 1) + 1
        raise ValueError(f"no longest form: {json.dumps(node)[:120]}")

    return size(schema)


@lru_cache(maxsize=64)
def text_caps(limits: ControlLimits = DEFAULT_LIMITS, bounds: Bounds = "range", max_perception: int = 4,
              max_tokens: int = DEFAULT_MAX_TOKENS) -> tuple[tuple[str, int], ...]:
    """The ``maxLength`` of each text field, so that the longest answer has at most ``max_tokens`` characters.

    The answer's fixed part (keys, punctuation, enum values, numbers, at most ``max_perception``
    entries and ``limits.max_signals`` signals) is counted first; what is left is shared by
    :data:`TEXT_SHARES` (``planning`` 4, each ``result`` 2, each ``justification`` 1), every cap
    between :data:`MIN_GRAMMAR_TEXT` and :data:`MAX_GRAMMAR_TEXT`; ``input`` gets
    :data:`INPUT_NAME_CHARS`. One character per token is the worst case of a byte-level
    tokenizer on ASCII text, so the longest answer fits in ``max_tokens`` tokens. When even the
    shortest caps do not fit, a warning is logged and the answer can still be cut off.
    """
    free_caps = {"planning": 0, "result": 0, "input": INPUT_NAME_CHARS, "justification": 0}
    fixed = longest_answer_chars(_trimmed_schema(limits, bounds, max_perception, free_caps))
    units = (TEXT_SHARES["planning"] + TEXT_SHARES["result"] * max_perception
             + TEXT_SHARES["justification"] * limits.max_signals)
    unit = max(0, max_tokens - fixed) // units
    caps = dict(free_caps)
    for name, share in TEXT_SHARES.items():
        caps[name] = min(MAX_GRAMMAR_TEXT, max(MIN_GRAMMAR_TEXT, share * unit))
    longest = longest_answer_chars(_trimmed_schema(limits, bounds, max_perception, caps))
    if longest > max_tokens:
        log.warning("decoding.budget_short", max_tokens=max_tokens, longest_answer_chars=longest,
                    hint="raise max_tokens or lower max_signals: an answer can be cut off at max_tokens")
    return tuple(caps.items())


def decoding_schema(limits: ControlLimits = DEFAULT_LIMITS, bounds: Bounds = "range",
                    max_perception: int = 4, max_tokens: int = DEFAULT_MAX_TOKENS) -> dict[str, Any]:
    """The response schema trimmed for constrained decoding (grammar-based JSON), with ``limits``.

    Distances and angles carry the scenario's actuation limits (:func:`bounded_number`), the
    control list at most ``limits.max_signals`` entries, the perception list at most
    ``max_perception``. Titles, descriptions and defaults are dropped; every property is
    required so small models emit all of them. Text fields get the small ``maxLength`` of
    :func:`text_caps` instead of the contract's 2,000 characters, so that the longest answer the
    grammar admits fits in ``max_tokens`` (:func:`longest_answer_chars`): a model that loops
    inside its planning is closed off at the cap rather than cut off at the token limit. The
    parser still enforces the full contract on whatever comes back.
    """
    caps = dict(text_caps(limits, bounds, max_perception, max_tokens))
    return _trimmed_schema(limits, bounds, max_perception, caps)


def response_format(mode: JsonMode, limits: ControlLimits = DEFAULT_LIMITS,
                    max_tokens: int = DEFAULT_MAX_TOKENS) -> dict[str, Any] | None:
    """The ``response_format`` request field for ``mode``, the scenario's ``limits`` and the
    answer's ``max_tokens`` (None: none).

    * ``json_schema``: OpenAI's structured-output shape, integer bounds (llama.cpp's
      ``llama-server``, vLLM, Ollama);
    * ``json_schema_enum``: ``{"type": "json_object", "schema": ...}`` with integer enums, the
      one shape the llama-cpp-python server reads (a ``json_schema`` request gets HTTP 500 there)
      and the one bound it honours; ``llama-server`` reads this shape too;
    * ``json_object``: any JSON object (OpenAI JSON mode), no schema;
    * ``none``: nothing asked; the prompt alone describes the answer.
    """
    mode = LEGACY_JSON_MODES.get(mode, mode)
    if mode == "json_object":
        return {"type": "json_object"}
    if mode == "json_schema_enum":
        return {"type": "json_object", "schema": decoding_schema(limits, "enum", max_tokens=max_tokens)}
    if mode == "json_schema":
        return {"type": "json_schema",
                "json_schema": {"name": "safeembodai_response",
                                "schema": decoding_schema(limits, "range", max_tokens=max_tokens),
                                "strict": False}}
    return None
