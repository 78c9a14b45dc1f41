"""litellm, imported once per process and quietly; and token counting as if for a given model.

``import litellm`` costs about 5 s and 165 MB, so nothing imports it until a backend needs it.
Before the import, ``LITELLM_LOCAL_MODEL_COST_MAP=True`` keeps litellm from fetching its cost
map from the internet and ``LITELLM_MODE=PRODUCTION`` keeps it from loading a ``.env`` file
from the working directory; after it, debug banners are switched off, httpx's and openai's loggers
are held at WARNING so no request (or header) is ever logged, and litellm's own at ERROR: its
warnings quote what a server sent (an unknown finish reason, say), and every failure reaches the
backend as an exception anyway.
"""

from __future__ import annotations

import logging
import os
import sys
from functools import lru_cache
from typing import Any, Literal

from safeembodai_core.models.token_estimate import message_tokens, text_tokens

TokenCounting = Literal["litellm", "estimate"]


@lru_cache(maxsize=1)
def import_litellm() -> Any:
    """The litellm module, configured for offline, quiet use (imported on first call only)."""
    if "litellm" not in sys.modules:
        os.environ["LITELLM_LOCAL_MODEL_COST_MAP"] = "True"
        os.environ["LITELLM_MODE"] = "PRODUCTION"
    import litellm

    litellm.suppress_debug_info = True
    litellm.set_verbose = False
    # token_counter must not fetch a tokenizer from a hub for some model names (llama, cohere, ...): offline
    litellm.disable_hf_tokenizer_download = True
    if hasattr(litellm, "telemetry"):
        litellm.telemetry = False
    for name in ("LiteLLM", "LiteLLM Router", "LiteLLM Proxy", "litellm"):
        logging.getLogger(name).setLevel(logging.ERROR)
    for name in ("httpx", "openai"):
        logging.getLogger(name).setLevel(logging.WARNING)
    return litellm


def estimate_tokens(messages: list[dict[str, Any]], text: str | None = None) -> int:
    """A quick approximation (:mod:`safeembodai_core.models.token_estimate`): about four characters
    a token, 85 per low-detail image; ``text``: an answer's tokens instead."""
    return text_tokens(text) if text is not None else message_tokens(messages)


def count_prompt_tokens(messages: list[dict[str, Any]], model: str, method: TokenCounting) -> int:
    """Prompt tokens of ``messages`` for ``model`` (images must be ``data:`` URLs)."""
    if method == "estimate":
        return estimate_tokens(messages)
    return int(import_litellm().token_counter(model=model, messages=messages))


def count_completion_tokens(text: str, model: str, method: TokenCounting) -> int:
    """Tokens of an answer ``text`` for ``model``."""
    if method == "estimate":
        return estimate_tokens([], text)
    return int(import_litellm().token_counter(model=model, text=text, count_response_tokens=True))
