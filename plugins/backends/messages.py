"""A :class:`~safeembodai_core.models.Prompt` as OpenAI-style chat messages, and the output format.

Shared by the litellm backends (what is sent) and the mock pilot (what would have been sent,
for token counting). Images become base64 ``data:`` URLs -- never http(s) URLs, which
litellm's token counter would try to download. Models without a system role (Gemma) get the
system prompt folded into the start of the user turn.
"""

from __future__ import annotations

import base64
import copy
from typing import Any, Literal

from safeembodai_core.models import ImagePart, Prompt, TextPart
from safeembodai_core.models.response import response_json_schema

ImageDetail = Literal["low", "high", "auto"]
JsonMode = Literal["json_object", "json_schema", "json_object_schema", "off"]
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


def decoding_schema(max_signals: int = 5, max_perception: int = 4) -> dict[str, Any]:
    """The response schema trimmed for constrained decoding (grammar-based JSON).

    Titles, descriptions, defaults and string length caps are dropped (a 2,000-character cap
    becomes a huge grammar); every property is required so small models emit all of them; the
    perception and control lists get small caps so a small model cannot loop until it runs
    out of tokens. The parser still enforces the full schema on whatever comes back.
    """
    schema = copy.deepcopy(response_json_schema())
    schema["properties"]["perception"].update(minItems=1, maxItems=max_perception)
    schema["properties"]["control"].update(minItems=1, maxItems=max_signals)

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


def response_format(mode: JsonMode) -> dict[str, Any] | None:
    """The ``response_format`` request field for ``mode`` (None: ask for nothing).

    ``json_object``: any JSON (OpenAI JSON mode); ``json_schema``: the OpenAI structured-output
    shape carrying :func:`decoding_schema` (vLLM, Ollama, llama.cpp's ``llama-server``);
    ``json_object_schema``: ``{"type": "json_object", "schema": ...}``, the only form the
    llama-cpp-python server turns into a grammar.
    """
    if mode == "json_object":
        return {"type": "json_object"}
    if mode == "json_object_schema":  # llama-cpp-python's server: JSON mode with a schema grammar
        return {"type": "json_object", "schema": decoding_schema()}
    if mode == "json_schema":
        return {"type": "json_schema",
                "json_schema": {"name": "safeembodai_response", "schema": decoding_schema(), "strict": False}}
    return None
