"""Control signals: the two motions the paper's LLM may command.

``straight`` moves the robot forward or backward by a distance in millimetres; ``turn`` rotates it
left (counter-clockwise) or right by an angle in degrees. The authors' release constrains both:
0 < distance < 400 mm and 0 < angle < 90 degrees. Those bounds are the *actuation contract* of
the robot, enforced for every command whatever defences are on; pass different
:class:`ControlLimits` for a robot with another contract. Non-finite, negative, zero and
out-of-limit values never parse, so they can never be executed.

``ControlLimits.enforce: false`` keeps the bounds as prompt text only (the authors' release does
not check them, ``profile: eyesim_release``); the hard caps :data:`HARD_MAX_DISTANCE_MM` and
:data:`HARD_MAX_ANGLE_DEG` hold whatever the setting: an LLM's answer is untrusted input.

The limits come from the validation context (``context={"limits": ...}``), which every reader
of an answer passes (:func:`~safeembodai_core.models.read_reply`, the Guard, the Gymnasium env).
A signal validated without one -- a stored record read back, whose answer was judged under its
scenario's limits when it was read -- is held to the hard caps only.
"""

from __future__ import annotations

from typing import Annotated, Literal, Union

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator

MAX_TEXT = 2000
#: Sanity caps no setting lifts: a straight of more than 10 m or a turn of more than a full circle
#: never parses (ours: far beyond any room the project simulates, and beyond the release's prompt bounds).
HARD_MAX_DISTANCE_MM = 10_000.0
HARD_MAX_ANGLE_DEG = 360.0


class ControlLimits(BaseModel):
    """The answer contract: exclusive upper bounds of the actuation contract (the prompt's control
    method ``m``) and how strictly a reply is read (:mod:`safeembodai_core.models.reply`)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    max_distance_mm: float = Field(400.0, gt=0, le=HARD_MAX_DISTANCE_MM, allow_inf_nan=False)
    max_angle_deg: float = Field(90.0, gt=0, le=HARD_MAX_ANGLE_DEG, allow_inf_nan=False)
    enforce: bool = Field(
        True, description="refuse a distance or angle at or above the bounds (false: the bounds are prompt text "
                          "only, as in the authors' release; the hard caps of 10 m and 360 deg still hold)")
    max_signals: int = Field(5, ge=1, le=50, description="most control signals in one answer")
    outside_text: Literal["refuse", "allow"] = Field(
        "refuse", description="text outside the one JSON object (beyond whitespace, one code fence and leading "
                              "reasoning blocks): refuse the answer, or allow it (for models without a JSON mode)")
    require_finish_reason: bool = Field(
        False, description="refuse a reply whose backend reports no finish reason (by default it is accepted "
                           "and recorded as not reported)")


DEFAULT_LIMITS = ControlLimits()
RECORD_LIMITS = ControlLimits(enforce=False)  # what a signal validated without limits is held to


def _limits(info: ValidationInfo) -> ControlLimits:
    """The context's limits; without them (a record read back) the hard caps only."""
    context = info.context if isinstance(info.context, dict) else {}
    limits = context.get("limits")
    return limits if isinstance(limits, ControlLimits) else RECORD_LIMITS


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
        limits = _limits(info)
        if limits.enforce and not value < limits.max_distance_mm:
            raise ValueError(f"distance must be below {limits.max_distance_mm:g} mm, got {value:g}")
        if not value <= HARD_MAX_DISTANCE_MM:
            raise ValueError(f"distance must be at most {HARD_MAX_DISTANCE_MM:g} mm (the hard cap), got {value:g}")
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
        limits = _limits(info)
        if limits.enforce and not value < limits.max_angle_deg:
            raise ValueError(f"angle must be below {limits.max_angle_deg:g} degrees, got {value:g}")
        if not value <= HARD_MAX_ANGLE_DEG:
            raise ValueError(f"angle must be at most {HARD_MAX_ANGLE_DEG:g} degrees (the hard cap), got {value:g}")
        return value

    @property
    def signed_angle_deg(self) -> float:
        """Rotation in degrees, counter-clockwise positive (left)."""
        return self.angle if self.direction == "left" else -self.angle

    def describe(self) -> str:
        return f"turn {self.direction} {self.angle:g} deg"


ControlSignal = Annotated[Union[Straight, Turn], Field(discriminator="command")]
