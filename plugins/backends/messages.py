"""A :class:`~safeembodai_core.models.Prompt` as OpenAI-style chat messages, and the output format.

Shared by the litellm backends (what is sent) and the mock pilot (what would have been sent,
for token counting). Images become base64 ``data:`` URLs -- never http(s) URLs, which
litellm's token counter would try to download. Models without a system role (Gemma) get the
system prompt folded into the start of the user turn.
"""

from __future__ import annotations

import base64
import copy
import math
from typing import Any, Literal

from safeembodai_core.models import ImagePart, Prompt, TextPart
from safeembodai_core.models.control import DEFAULT_LIMITS, ControlLimits
from safeembodai_core.models.response import response_json_schema

ImageDetail = Literal["low", "high", "auto"]
JsonMode = Literal["json_schema", "json_schema_enum", "json_object", "none"]
Bounds = Literal["range", "enum"]
# names of earlier releases, still accepted: json_object_schema had the enum form's shape, unbounded
LEGACY_JSON_MODES = {"json_object_schema": "json_schema_enum", "off": "none"}
MAX_ENUM_VALUES = 400
_DROP_KEYS = ("title", "description", "maxLength", "default")


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


def decoding_schema(limits: ControlLimits = DEFAULT_LIMITS, bounds: Bounds = "range",
                    max_perception: int = 4) -> dict[str, Any]:
    """The response schema trimmed for constrained decoding (grammar-based JSON), with ``limits``.

    Distances and angles carry the scenario's actuation limits (:func:`bounded_number`), the
    control list at most ``limits.max_signals`` entries. Titles, descriptions, defaults and
    string length caps are dropped (a 2,000-character cap becomes a huge grammar); every
    property is required so small models emit all of them; the perception list gets a small cap
    so a small model cannot loop until it runs out of tokens. The parser still enforces the full
    contract on whatever comes back.
    """
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

    return trim(schema)


def response_format(mode: JsonMode, limits: ControlLimits = DEFAULT_LIMITS) -> dict[str, Any] | None:
    """The ``response_format`` request field for ``mode`` and the scenario's ``limits`` (None: none).

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
        return {"type": "json_object", "schema": decoding_schema(limits, "enum")}
    if mode == "json_schema":
        return {"type": "json_schema",
                "json_schema": {"name": "safeembodai_response", "schema": decoding_schema(limits, "range"),
                                "strict": False}}
    return None
