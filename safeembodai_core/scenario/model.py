"""The scenario schema. Every key is documented in ``docs/scenarios.md``."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from ..loop.defences import Defences
from ..metrics.settings import MetricSettings
from ..models import ControlLimits
from ..models.prompt import DEFAULT_INSTRUCTION, DEFAULT_TASK
from ..plugin.refs import ComponentRef, unique_keys
from .profiles import apply_profile


class Condition(BaseModel):
    """An attack setting: which attackers act on every trial of the cell."""

    model_config = ConfigDict(extra="forbid")

    attackers: list[ComponentRef] = Field(default_factory=list)

    @field_validator("attackers")
    @classmethod
    def _unique(cls, refs: list[ComponentRef]) -> list[ComponentRef]:
        return unique_keys(refs, "attacker")


#: ``arms`` and ``conditions`` when a scenario gives none, as written in YAML.
DEFAULT_ARMS: dict[str, Any] = {
    "baseline": {},
    "safeembodai": {"security_prefix": True, "state_management": True, "safety_validation": True},
}
DEFAULT_CONDITIONS: dict[str, Any] = {"no_attack": {}, "attack": {"attackers": ["prompt_injection"]}}


def _default_arms() -> dict[str, Defences]:
    return {name: Defences.model_validate(keys) for name, keys in DEFAULT_ARMS.items()}


def _default_conditions() -> dict[str, Condition]:
    return {name: Condition.model_validate(keys) for name, keys in DEFAULT_CONDITIONS.items()}


class ProfileRecord(BaseModel):
    """The profile a scenario applied (``profile: <name>``) and the keys the scenario set otherwise."""

    model_config = ConfigDict(extra="forbid")

    name: str
    overridden: dict[str, dict[str, Any]] = Field(default_factory=dict)


class Scenario(BaseModel):
    """An ablation: cells are environments x arms x conditions, each run for ``trials`` trials."""

    model_config = ConfigDict(extra="forbid")

    name: str = Field(min_length=1, pattern=r"^[A-Za-z0-9_.-]+$")
    description: str = ""
    seed: int = Field(0, ge=0)
    trials: int = Field(10, ge=1, le=100_000)
    max_steps: int = Field(20, ge=1, le=10_000)
    budget: Literal["steps", "attempts"] = "steps"
    instruction: str = DEFAULT_INSTRUCTION
    task: str = DEFAULT_TASK
    limits: ControlLimits = Field(default_factory=ControlLimits)
    environments: list[ComponentRef] = Field(min_length=1)
    backend: ComponentRef = Field(default_factory=lambda: ComponentRef(use="mock"))
    perception: ComponentRef = Field(default_factory=lambda: ComponentRef(use="images"))
    prompt_builder: ComponentRef = Field(default_factory=lambda: ComponentRef(use="jinja"))
    state: ComponentRef = Field(default_factory=lambda: ComponentRef(use="sqlite"))
    arms: dict[str, Defences] = Field(default_factory=_default_arms, min_length=1)
    conditions: dict[str, Condition] = Field(default_factory=_default_conditions, min_length=1)
    metrics: MetricSettings = Field(default_factory=MetricSettings)
    profile: ProfileRecord | None = None

    @model_validator(mode="before")
    @classmethod
    def _apply_profile(cls, data: Any) -> Any:
        if isinstance(data, dict) and data.get("profile") is not None:
            return apply_profile(data, DEFAULT_ARMS, DEFAULT_CONDITIONS)
        return data

    @field_validator("environments")
    @classmethod
    def _unique_labels(cls, refs: list[ComponentRef]) -> list[ComponentRef]:
        return unique_keys(refs, "environment")

    @model_validator(mode="after")
    def _names_are_plain(self) -> "Scenario":
        labels = [e.key for e in self.environments]
        for what, names in (("environment label", labels), ("arm", self.arms), ("condition", self.conditions)):
            for name in names:
                if not name or "/" in name:
                    raise ValueError(f"{what} name {name!r} must be non-empty and contain no '/'")
                if "__" in name or name.startswith("_") or name.endswith("_"):
                    # a trial's files join these names with '__' (run_files.trial_file_name): two trials
                    # of different cells would share a file
                    raise ValueError(f"{what} name {name!r} must not contain '__' or start or end with '_' "
                                     "(a trial's files join the names of its cell with '__')")
        return self

    def environment(self, label: str) -> ComponentRef:
        for ref in self.environments:
            if ref.key == label:
                return ref
        raise KeyError(label)

    def cells(self) -> list[tuple[str, str, str]]:
        """Every (environment label, arm, condition), in file order."""
        return [(e.key, a, c) for e in self.environments for a in self.arms for c in self.conditions]
