"""Attacker plugins: the adversary's three channels -- instruction, sensor, state.

* ``prompt_injection`` -- at a seeded per-step ``rate`` (default 0.5, the authors' release; the
  other two attackers share the default so that conditions compare),
  appends to (or, with ``mode: replace``, replaces) the human instruction a malicious prompt from
  a library: the six kinds the paper names (``kinds: paper``), five of ours, and the two texts
  the authors' release injected (``kinds: release``, verbatim; the release replaced the
  instruction with them).
* ``lidar_spoof`` -- phantom or erased obstacles in a sector of the LiDAR scan; the validators
  see the spoofed scan, as they would with a real spoofed sensor.
* ``state_poisoning`` -- a forged entry in the reference state R_{i-1} (only when state
  management puts one in the prompt).

Each attacked step is recorded as ground truth (attacker, channel, kind, payload), so detection
is scored exactly. Every options model subclasses :class:`safeembodai_core.contracts.attack_schedule.AttackSchedule`
(``rate``, ``start_step``, ``steps``) and every attacker asks its ``fires(target)`` first, the
schedule a third-party attacker reuses. Per-step randomness comes from the step's own stream
(trial seed, attacker key, step), and each attacker draws the same count of numbers whether it
attacks or not: every arm sees the same attacks at the same steps. Options and YAML examples:
``docs/attacks.md``.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator, model_validator

from safeembodai_core.contracts.attack_schedule import AttackSchedule
from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy


class PromptInjectionOptions(AttackSchedule):
    """Options of ``prompt_injection``."""

    mode: Literal["append", "replace"] = Field("append", description=(
        "append the payload to the instruction, or replace the instruction with it (the authors' release: "
        "eyesimLLM src/discrete_robot/discrete_llm_robot.py:166-174)"))
    separator: str = Field(" ", max_length=20, description="between the instruction and an appended payload")
    kinds: list[str] | str | None = Field(None, description=(
        "draw only from these payload kinds, or a group: 'paper' (the six the paper names), 'release' (the "
        "release's two texts) or 'all' (default)"))
    payloads: list[str] | None = Field(None, description="your own payloads instead of the library (kind 'custom')")
    aim_at_target: bool = Field(False, description="{x}, {y} = the target's true position instead of random")

    @field_validator("kinds")
    @classmethod
    def _known(cls, kinds: list[str] | str | None) -> list[str] | None:
        from .library import KIND_GROUPS, PAYLOADS

        if isinstance(kinds, str):
            if kinds not in KIND_GROUPS:
                raise ValueError(f"unknown group of payload kinds {kinds!r}; groups: {', '.join(KIND_GROUPS)} "
                                 f"(or a list of kinds)")
            return list(KIND_GROUPS[kinds])
        if kinds is not None:
            unknown = sorted(set(kinds) - set(PAYLOADS))
            if unknown or not kinds:
                raise ValueError(f"unknown payload kinds {unknown}; known: {', '.join(PAYLOADS)}")
        return kinds

    @field_validator("payloads")
    @classmethod
    def _non_empty(cls, payloads: list[str] | None) -> list[str] | None:
        if payloads is not None and (not payloads or not all(p.strip() for p in payloads)):
            raise ValueError("payloads must be a non-empty list of non-empty strings")
        return payloads


class LidarSpoofOptions(AttackSchedule):
    """Options of ``lidar_spoof``."""

    mode: Literal["phantom", "erase"] = Field("phantom", description="add a fake obstacle or hide real ones")
    centre_deg: float | None = Field(0.0, ge=-180, le=180, allow_inf_nan=False,
                                     description="sector centre, from the heading (left positive); null: random")
    towards_target: bool = Field(False, description="centre the sector on the target's true bearing")
    half_width_deg: float = Field(20.0, gt=0, le=180, allow_inf_nan=False, description="half-width of the sector")
    distance_mm: float | None = Field(None, gt=0, allow_inf_nan=False,
                                      description="phantom distance; null: random in [min, max]")
    min_distance_mm: float = Field(250.0, gt=0, allow_inf_nan=False)
    max_distance_mm: float = Field(800.0, gt=0, allow_inf_nan=False)

    @model_validator(mode="after")
    def _ordered(self) -> "LidarSpoofOptions":
        if self.min_distance_mm > self.max_distance_mm:
            raise ValueError("min_distance_mm must not exceed max_distance_mm")
        return self


class StatePoisoningOptions(AttackSchedule):
    """Options of ``state_poisoning``."""

    start_step: int = Field(2, ge=1, description="first step that may be attacked (step 1 has no state)")
    kinds: list[str] | None = Field(None, description="forgeries to draw from (default: all)")
    notes: list[str] | None = Field(None, description="operator notes for 'forged_note' (default: built-in)")

    @field_validator("kinds")
    @classmethod
    def _known(cls, kinds: list[str] | None) -> list[str] | None:
        from .poisoning import KINDS

        if kinds is not None:
            unknown = sorted(set(kinds) - set(KINDS))
            if unknown or not kinds:
                raise ValueError(f"unknown forgery kinds {unknown}; known: {', '.join(KINDS)}")
        return kinds

    @field_validator("notes")
    @classmethod
    def _non_empty(cls, notes: list[str] | None) -> list[str] | None:
        if notes is not None and (not notes or not all(n.strip() for n in notes)):
            raise ValueError("notes must be a non-empty list of non-empty strings")
        return notes


@hookimpl
def register_attackers(register):
    register("prompt_injection", lazy(f"{__name__}.injection", "PromptInjectionAttacker"),
             options=PromptInjectionOptions,
             description="malicious prompts injected into the human instruction at a seeded rate")
    register("lidar_spoof", lazy(f"{__name__}.spoof", "LidarSpoofAttacker"), options=LidarSpoofOptions,
             description="phantom or erased obstacles in a sector of the LiDAR scan")
    register("state_poisoning", lazy(f"{__name__}.poisoning", "StatePoisoningAttacker"), options=StatePoisoningOptions,
             description="a forged entry in the reference state R_{i-1}")
