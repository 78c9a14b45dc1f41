"""The framework's offline backends as an Inspect model provider: ``--model safeembodai/mock``.

``safeembodai/<name>`` builds the registered LLM backend ``<name>`` (``mock``, the simulated
pilot; ``scripted``; a plugin's own) with the ``-M key=value`` model arguments as its options,
validated by the backend's options model exactly as a scenario's ``backend.options`` are.

A call made by :class:`~.bridge.InspectBackend` carries the prompt's sections, modality names
and the state of the generator the loop drew for that call (the user message's metadata), so
the pilot answers exactly what it answers under ``safeembodai ablate``: same prompt, same dice,
same per-cell MOER for the same seed. A message from anything else (a plain Inspect task) is
read as text and images with no sections, and the dice are seeded from its text.
"""

from __future__ import annotations

import hashlib
from typing import Any

import anyio.to_thread
import numpy as np
from inspect_ai.model import ChatMessage, GenerateConfig, ModelAPI, ModelOutput, ModelUsage

from ...components import BuildContext
from ...errors import SafeEmbodAIError
from .bridge import prompt_from_messages

_STOP = {"length": "max_tokens", "max_tokens": "max_tokens", "content_filter": "content_filter"}


class SafeEmbodAIModelAPI(ModelAPI):
    """Answers with a registered SafeEmbodAI backend (``model_name`` is its name)."""

    def __init__(self, model_name: str, base_url: str | None = None, api_key: str | None = None,
                 config: GenerateConfig = GenerateConfig(), **model_args: Any) -> None:
        super().__init__(model_name=model_name, base_url=base_url, api_key=api_key, config=config)
        from ...plugins import load_plugins

        context = BuildContext(component=model_name, kind="llm_backend", seed=0, run_dir=None, label="inspect")
        try:
            self.backend = load_plugins().registry.build("llm_backend", model_name, dict(model_args), context)
        except SafeEmbodAIError as error:
            raise ValueError(f"safeembodai/{model_name}: {error}") from None

    def max_connections(self) -> int:
        return 8  # it computes locally: more would only queue on the shared cores

    async def generate(self, input: list[ChatMessage], tools: list[Any], tool_choice: Any,
                       config: GenerateConfig) -> ModelOutput:
        prompt, rng = prompt_from_messages(input)
        if rng is None:
            digest = hashlib.blake2b((prompt.system + prompt.user_text).encode(), digest_size=8).digest()
            rng = np.random.default_rng(int.from_bytes(digest, "big"))
        reply = await anyio.to_thread.run_sync(self.backend.complete, prompt, rng)
        output = ModelOutput.from_content(self.model_name, reply.text,
                                          stop_reason=_STOP.get(str(reply.finish_reason), "stop"))  # type: ignore[arg-type]
        usage = reply.usage
        output.usage = ModelUsage(input_tokens=usage.prompt_tokens, output_tokens=usage.completion_tokens,
                                  total_tokens=usage.prompt_tokens + usage.completion_tokens)
        return output

    def close(self) -> None:
        self.backend.close()
