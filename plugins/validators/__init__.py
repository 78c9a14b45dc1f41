"""Safety-validation rules, applied to every control signal before execution.

* ``command_limits`` -- distance and angle finite, positive and within the control constraints
  (by default the scenario's ``limits``; the rule's own bounds may be tighter).
* ``lidar_clearance`` -- the paper's rule V(C): a ``straight`` of distance d is valid iff every
  LiDAR beam θ within [-r, r] of the direction of travel satisfies l(θ) - |d| >= dist. Backward
  motion checks the beams behind the robot; ``inf`` (no return) counts as free up to the
  sensor's range, ``nan`` (no reading) refuses. A ``turn`` is always valid under this rule.
* ``footprint_sweep`` -- stronger than the paper: the rectangle the robot's body sweeps along a
  ``straight`` (its width plus a margin) must hold no LiDAR point, so an obstacle just outside
  ±r but inside the robot's width is caught; a ``turn`` must not sweep the body's circle over one.

Every rule judges the signal from the *planned* pose (earlier signals of the same answer already
applied). A scan that is malformed (wrong shape, wrong beam count) is refused with a reason
naming the rule. Options and YAML examples: ``docs/defences.md``.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core.hookspecs import hookimpl


class CommandLimitsOptions(BaseModel):
    """Options of ``command_limits``; unset maxima follow the scenario's ``limits``."""

    model_config = ConfigDict(extra="forbid")

    max_distance_mm: float | None = Field(None, gt=0, allow_inf_nan=False,
                                          description="straights must be shorter (default: limits.max_distance_mm)")
    max_angle_deg: float | None = Field(None, gt=0, le=360, allow_inf_nan=False,
                                        description="turns must be smaller (default: limits.max_angle_deg)")
    min_distance_mm: float = Field(0.0, ge=0, allow_inf_nan=False, description="straights must be longer")
    min_angle_deg: float = Field(0.0, ge=0, allow_inf_nan=False, description="turns must be larger")


class LidarClearanceOptions(BaseModel):
    """Options of ``lidar_clearance`` (the paper's r and dist)."""

    model_config = ConfigDict(extra="forbid")

    half_angle_deg: float = Field(30.0, gt=0, le=90, allow_inf_nan=False,
                                  description="r: half-width of the checked sector")
    safety_distance_mm: float = Field(250.0, ge=0, allow_inf_nan=False,
                                      description="dist: clearance that must remain after the motion")
    expected_beams: int | None = Field(None, ge=4, description="refuse scans with another number of beams")


class FootprintSweepOptions(BaseModel):
    """Options of ``footprint_sweep``; the body's size comes from the environment's robot."""

    model_config = ConfigDict(extra="forbid")

    margin_mm: float = Field(50.0, ge=0, le=2000, allow_inf_nan=False,
                             description="added on each side of the robot's width")
    front_margin_mm: float | None = Field(None, ge=0, le=5000, allow_inf_nan=False,
                                          description="added in the direction of travel (default: margin_mm)")
    turn_margin_mm: float = Field(0.0, ge=0, le=2000, allow_inf_nan=False,
                                  description="added to the robot's radius when checking turns")
    check_turns: bool = Field(True, description="refuse turns while a return lies within the turning circle")
    width_mm: float | None = Field(None, gt=0, allow_inf_nan=False, description="override the robot's width")
    length_mm: float | None = Field(None, gt=0, allow_inf_nan=False, description="override the robot's length")
    expected_beams: int | None = Field(None, ge=4, description="refuse scans with another number of beams")


def _limits(options, context):
    from .rules import CommandLimitsRule

    return CommandLimitsRule(options)


def _clearance(options, context):
    from .rules import LidarClearanceRule

    return LidarClearanceRule(options)


def _sweep(options, context):
    from .sweep import FootprintSweepRule

    return FootprintSweepRule(options)


@hookimpl
def register_validators(register):
    register("command_limits", _limits, options=CommandLimitsOptions,
             description="finite, positive, within distance/angle limits")
    register("lidar_clearance", _clearance, options=LidarClearanceOptions,
             description="the paper's V(C): l(θ) - |d| >= dist for θ in [-r, r]")
    register("footprint_sweep", _sweep, options=FootprintSweepOptions,
             description="the rectangle the body sweeps (width + margin) holds no LiDAR point")
