"""The options of the ``scripted`` backend (the package registers them)."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field


class ScriptedOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    responses: list[str | dict[str, Any]] = Field(min_length=1, description="answers, in order")
    then: Literal["repeat", "fail"] = "repeat"
