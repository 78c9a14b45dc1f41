"""The scripted backend's implementation (see the package for the plugin and ``options.py`` for its options)."""

from __future__ import annotations

import json
from typing import TYPE_CHECKING, Any

from safeembodai_core.contracts.components import BackendReply, LLMBackend
from safeembodai_core.errors import BackendError

if TYPE_CHECKING:
    from .options import ScriptedOptions


class ScriptedBackend(LLMBackend):
    """Replays the answers of its options, then repeats the last or fails (``then``)."""

    def __init__(self, options: "ScriptedOptions") -> None:
        self.answers = [a if isinstance(a, str) else json.dumps(a) for a in options.responses]
        self.then = options.then
        self.calls = 0
        self.prompts: list[Any] = []

    def complete(self, prompt, rng) -> BackendReply:
        self.prompts.append(prompt)
        index = self.calls
        self.calls += 1
        if index >= len(self.answers):
            if self.then == "fail":
                raise BackendError(f"scripted backend: no answer left after {len(self.answers)}")
            index = len(self.answers) - 1
        return BackendReply(text=self.answers[index], model="scripted")
