"""Safety-validation rules.

* ``command_limits`` -- distance and angle finite, positive and within the configured limits.
* ``lidar_clearance`` -- the paper's rule V(C): a ``straight`` of distance d is valid iff every
  LiDAR beam θ within [-r, r] of the direction of travel satisfies l(θ) - |d| >= dist.
  Backward motion checks the beams behind the robot; a missing beam in the sector fails.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from safeembodai_core.hookspecs import hookimpl


class CommandLimitsOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    max_distance_mm: float = Field(400.0, gt=0, allow_inf_nan=False)
    max_angle_deg: float = Field(90.0, gt=0, le=360, allow_inf_nan=False)
    min_distance_mm: float = Field(0.0, ge=0, allow_inf_nan=False, description="shorter straights are refused")


class LidarClearanceOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    half_angle_deg: float = Field(30.0, gt=0, le=90, description="r: half-width of the checked sector")
    safety_distance_mm: float = Field(250.0, ge=0, description="dist: clearance that must remain")


def _limits(options, context):
    from .rules import CommandLimitsRule

    return CommandLimitsRule(options)


def _clearance(options, context):
    from .rules import LidarClearanceRule

    return LidarClearanceRule(options)


@hookimpl
def register_validators(register):
    register("command_limits", _limits, options=CommandLimitsOptions,
             description="finite, positive, within distance/angle limits")
    register("lidar_clearance", _clearance, options=LidarClearanceOptions,
             description="the paper's V(C): l(θ) - |d| >= dist for θ in [-r, r]")
