"""The rough token count of a call whose usage no one reported: about four characters a token.

Used where a server's (or Inspect's) usage is missing or unusable and no tokenizer for the model
is at hand: a paid call is then counted, never taken as 0 (``TokenUsage.estimated``). The litellm
backend counts chat messages with it when litellm cannot tokenize the model; Inspect's bridge
counts a prompt with it.
"""

from __future__ import annotations

from typing import Any

from .observation import ImagePart
from .prompt import Prompt
from .records import TokenUsage

CHARS_PER_TOKEN = 4
#: Tokens of one image part by vision detail (OpenAI's low-detail figure; high adds four tiles).
IMAGE_TOKENS = {"low": 85, "high": 85 + 4 * 170, "auto": 85}
#: Tokens a chat message costs besides its content, and a request besides its messages.
PER_MESSAGE, PER_REQUEST = 4, 3


def text_tokens(text: str) -> int:
    """An answer's (or a text part's) tokens: at least 1."""
    return max(1, round(len(text) / CHARS_PER_TOKEN))


def message_tokens(messages: list[dict[str, Any]]) -> int:
    """Tokens of OpenAI-style chat messages (``content`` text, or parts ``text`` / ``image_url``)."""
    total = PER_REQUEST
    for message in messages:
        total += PER_MESSAGE
        content = message["content"]
        parts: list[dict[str, Any]] = [{"type": "text", "text": content}] if isinstance(content, str) else content
        for part in parts:
            if part["type"] == "text":
                total += round(len(part["text"]) / CHARS_PER_TOKEN)
            else:
                total += IMAGE_TOKENS.get(part["image_url"].get("detail", "auto"), IMAGE_TOKENS["low"])
    return total


def prompt_tokens(prompt: Prompt, detail: str = "low") -> int:
    """Tokens of a :class:`Prompt` sent as a system and a user message."""
    total = PER_REQUEST + PER_MESSAGE * (2 if prompt.system else 1) + round(len(prompt.system) / CHARS_PER_TOKEN)
    for part in prompt.user:
        total += (IMAGE_TOKENS.get(detail, IMAGE_TOKENS["low"]) if isinstance(part, ImagePart)
                  else round(len(part.text) / CHARS_PER_TOKEN))
    return total


def estimated_usage(prompt: Prompt, answer: str, detail: str = "low") -> TokenUsage:
    """A call's usage counted here: the prompt's and the answer's rough counts, marked estimated."""
    return TokenUsage(prompt_tokens=prompt_tokens(prompt, detail), completion_tokens=text_tokens(answer),
                      estimated=True)
