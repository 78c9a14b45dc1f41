"""A reference to a named component with its options, as written in scenarios.

In YAML a reference is either the bare name (``lidar_clearance``) or a mapping
(``{use: lidar_clearance, options: {half_angle_deg: 20}}``). ``label`` names the reference in
results when one component is used twice with different options.
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator


class ComponentRef(BaseModel):
    model_config = ConfigDict(extra="forbid")

    use: str = Field(min_length=1, description="registered component name")
    options: dict[str, Any] = Field(default_factory=dict)
    label: str | None = None

    @model_validator(mode="before")
    @classmethod
    def _from_name(cls, value: Any) -> Any:
        return {"use": value} if isinstance(value, str) else value

    @property
    def key(self) -> str:
        return self.label or self.use


def unique_keys(refs: list[ComponentRef], what: str) -> list[ComponentRef]:
    """Labels name results and seed random streams: two uses of one component need distinct labels."""
    keys = [r.key for r in refs]
    repeated = sorted({k for k in keys if keys.count(k) > 1})
    if repeated:
        raise ValueError(f"{what} labels must be unique; repeated: {', '.join(repeated)} (give each a 'label')")
    return refs


def ref(value: str | dict[str, Any] | ComponentRef) -> ComponentRef:
    return value if isinstance(value, ComponentRef) else ComponentRef.model_validate(value)
