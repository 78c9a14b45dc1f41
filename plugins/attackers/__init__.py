"""Attacker plugins.

* ``prompt_injection`` -- at a seeded per-step ``rate``, appends to (or replaces) the human
  instruction a malicious prompt from a library covering the paper's examples. Every injected
  step is recorded as ground truth (attacker, kind, payload), so detection is scored exactly.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator

from safeembodai_core.hookspecs import hookimpl


class PromptInjectionOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    rate: float = Field(0.3, ge=0.0, le=1.0, description="probability that a step is attacked")
    mode: Literal["append", "replace"] = Field("append", description="attach to or replace the instruction")
    kinds: list[str] | None = Field(None, description="draw only from these payload kinds (default: all)")
    payloads: list[str] | None = Field(None, description="your own payloads instead of the library")
    start_step: int = Field(1, ge=1, description="first step that may be attacked")

    @field_validator("kinds")
    @classmethod
    def _known(cls, kinds: list[str] | None) -> list[str] | None:
        from .library import PAYLOADS

        if kinds is not None:
            unknown = sorted(set(kinds) - set(PAYLOADS))
            if unknown or not kinds:
                raise ValueError(f"unknown payload kinds {unknown}; known: {', '.join(PAYLOADS)}")
        return kinds


def _injection(options, context):
    from .injection import PromptInjectionAttacker

    return PromptInjectionAttacker(options)


@hookimpl
def register_attackers(register):
    register("prompt_injection", _injection, options=PromptInjectionOptions,
             description="malicious prompts injected into the human instruction at a seeded rate")
