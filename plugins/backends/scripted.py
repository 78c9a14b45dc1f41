"""``scripted``: replays answers given in its options, for tests and reproducible demos.

Each trial builds a fresh backend, so every trial replays from the first answer. Entries may be
JSON objects (sent as JSON text) or raw strings (sent as is, malformed or not). After the last
entry it repeats the last (``then: repeat``) or fails like an outage (``then: fail``). It reports
no token usage: it sends nothing anywhere.
"""

from __future__ import annotations

import json
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core.components import BackendReply, LLMBackend
from safeembodai_core.errors import BackendError
from safeembodai_core.hookspecs import hookimpl


class ScriptedOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    responses: list[str | dict[str, Any]] = Field(min_length=1, description="answers, in order")
    then: Literal["repeat", "fail"] = "repeat"


class ScriptedBackend(LLMBackend):
    def __init__(self, options: ScriptedOptions) -> None:
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


@hookimpl
def register_llm_backends(register):
    register("scripted", lambda options, context: ScriptedBackend(options), options=ScriptedOptions,
             description="replays answers from its options (tests, demos)")
