"""Control signals: the two motions the paper's LLM may command.

``straight`` moves the robot forward or backward by a distance in millimetres; ``turn`` rotates it
left (counter-clockwise) or right by an angle in degrees. The authors' release constrains both:
0 < distance < 400 mm and 0 < angle < 90 degrees. Those bounds are the *actuation contract* of
the robot, enforced for every command whatever defences are on; pass different
:class:`ControlLimits` for a robot with another contract. Non-finite, negative, zero and
out-of-limit values never parse, so they can never be executed.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

MAX_TEXT = 2000


class ControlLimits(BaseModel):
    """The answer contract: exclusive upper bounds of the actuation contract (the prompt's control
    method ``m``) and how strictly a reply is read (:mod:`safeembodai_core.models.reply`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    max_distance_mm: float = Field(400.0, gt=0, allow_inf_nan=False)
    max_angle_deg: float = Field(90.0, gt=0, le=360, allow_inf_nan=False)
    max_signals: int = Field(5, ge=1, le=50, description="most control signals in one answer")
    outside_text: Literal["refuse", "allow"] = Field(
        "refuse", description="text outside the one JSON object (beyond whitespace, one code fence and leading "
                              "reasoning blocks): refuse the answer, or allow it (for models without a JSON mode)")
    require_finish_reason: bool = Field(
        False, description="refuse a reply whose backend reports no finish reason (by default it is accepted "
                           "and recorded as not reported)")


DEFAULT_LIMITS = ControlLimits()


def _limits(info: ValidationInfo) -> ControlLimits:
    context = info.context or {}
    limits = context.get("limits", DEFAULT_LIMITS) if isinstance(context, dict) else DEFAULT_LIMITS
    return limits


class _Signal(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Straight(_Signal):
    """Move straight ``forward`` or ``backward`` by ``distance`` millimetres."""

    command: Literal["straight"]
    direction: Literal["forward", "backward"]
    distance: float = Field(gt=0, strict=True, allow_inf_nan=False, description="millimetres, 0 < d < limit")
    justification: str = Field("", max_length=MAX_TEXT)

    @field_validator("distance")
    @classmethod
    def _within_limit(cls, value: float, info: ValidationInfo) -> float:
        limit = _limits(info).max_distance_mm
        if not value < limit:
            raise ValueError(f"distance must be below {limit:g} mm, got {value:g}")
        return value

    @property
    def signed_distance_mm(self) -> float:
        """Distance along the heading: negative when moving backward."""
        return self.distance if self.direction == "forward" else -self.distance

    def describe(self) -> str:
        return f"straight {self.direction} {self.distance:g} mm"


class Turn(_Signal):
    """Turn ``left`` (counter-clockwise) or ``right`` by ``angle`` degrees."""

    command: Literal["turn"]
    direction: Literal["left", "right"]
    angle: float = Field(gt=0, strict=True, allow_inf_nan=False, description="degrees, 0 < angle < limit")
    justification: str = Field("", max_length=MAX_TEXT)

    @field_validator("angle")
    @classmethod
    def _within_limit(cls, value: float, info: ValidationInfo) -> float:
        limit = _limits(info).max_angle_deg
        if not value < limit:
            raise ValueError(f"angle must be below {limit:g} degrees, got {value:g}")
        return value

    @property
    def signed_angle_deg(self) -> float:
        """Rotation in degrees, counter-clockwise positive (left)."""
        return self.angle if self.direction == "left" else -self.angle

    def describe(self) -> str:
        return f"turn {self.direction} {self.angle:g} deg"


ControlSignal = Annotated[Union[Straight, Turn], Field(discriminator="command")]
