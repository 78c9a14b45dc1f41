"""The options of the ``scripted`` backend (the package registers them)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import Field

from safeembodai_core.contracts.descriptions import BackendDescription, BackendOptions


class ScriptedOptions(BackendOptions):
    responses: list[str | dict[str, Any]] = Field(min_length=1, description="answers, in order")
    then: Literal["repeat", "fail"] = "repeat"

    def describe(self) -> BackendDescription:
        return BackendDescription(model="none: answers replayed from the scenario",
                                  simulated="scripted answers (scripted): not a measurement of an LLM",
                                  why="Every answer is replayed from the scenario: every number below follows "
                                      "from that script.", pilot="scripted answers (scripted), not an LLM")
