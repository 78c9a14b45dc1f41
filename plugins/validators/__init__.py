"""Safety-validation rules, applied to every control signal before execution.

* ``command_limits`` -- distance and angle finite, positive and within the control constraints
  (by default the scenario's ``limits``; the rule's own bounds may be tighter).
* ``lidar_clearance`` -- the paper's rule V(C): a ``straight`` of distance d is valid iff every
  LiDAR beam θ within [-r, r] of the direction of travel satisfies l(θ) - |d| >= dist. Backward
  motion checks the beams behind the robot; ``inf`` (no return) counts as free up to the
  sensor's range, ``nan`` (no reading) refuses. After an earlier straight of the same plan the
  rule judges the measured points whose bearing from the planned pose lies within ±r (see
  ``ValidationContext.nearest_in_sector``). ``dist`` is never changed silently: see
  ``LidarClearanceOptions``. A ``turn`` is always valid under this rule (the paper), unless
  ``turns: ahead`` checks the same sector ahead of where it starts with d = 0 (the authors' release).
* ``footprint_sweep`` -- stronger than the paper: the rectangle the robot's body sweeps along a
  ``straight`` (its width plus a margin) must hold no LiDAR point, so an obstacle just outside
  ±r but inside the robot's width is caught; a ``turn`` must not sweep the body's circle over one.
* ``swept_body`` -- the robot default (``Guard``, ``guard-bag``): the exact region the body (its
  disc or ``RobotSpec.footprint_mm``, plus a margin) sweeps along a straight, a turn in place or a
  held velocity must hold no return and no space the scan did not see; it also says when the body
  would first touch something (``validate_motion``), for the time before collision and speed limits.
* ``moving_obstacles`` -- beyond the paper: returns that moved between the trial's last two scans
  (both in the room frame) are movers with a velocity; each gets possible courses wandering
  around it, and a ``straight`` whose body comes within a margin of at least ``max_risk`` of one
  mover's courses, at some moment of its execution after the think time, is refused. It judges
  movers only: pair it with ``lidar_clearance`` or ``footprint_sweep``.

Every rule judges the signal from the *planned* pose (earlier signals of the same answer already
applied). A scan that is malformed (wrong shape, wrong beam count) is refused with a reason
naming the rule. Options and YAML examples: ``docs/defences.md``.
"""

from __future__ import annotations

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy

from .options import (
    DEFAULT_SAFETY_DISTANCE_MM,
    CommandLimitsOptions,
    FootprintSweepOptions,
    LidarClearanceOptions,
    MovingObstaclesOptions,
    SweptBodyOptions,
)

__all__ = ["DEFAULT_SAFETY_DISTANCE_MM", "CommandLimitsOptions", "FootprintSweepOptions", "LidarClearanceOptions",
           "MovingObstaclesOptions", "SweptBodyOptions", "register_validators"]


@hookimpl
def register_validators(register):
    register("command_limits", lazy(f"{__name__}.rules", "CommandLimitsRule"), options=CommandLimitsOptions,
             description="finite, positive, within distance/angle limits")
    register("lidar_clearance", lazy(f"{__name__}.rules", "LidarClearanceRule"), options=LidarClearanceOptions,
             description="the paper's V(C): l(θ) - |d| >= dist for θ in [-r, r]")
    register("footprint_sweep", lazy(f"{__name__}.sweep", "FootprintSweepRule"), options=FootprintSweepOptions,
             description="the rectangle the body sweeps (width + margin) holds no LiDAR point")
    register("swept_body", lazy(f"{__name__}.swept_body", "SweptBodyRule"), options=SweptBodyOptions,
             description="the exact region the body (disc or footprint + margin) sweeps holds no return or "
                         "unseen space (straights, turns, held twists)")
    register("moving_obstacles", lazy(f"{__name__}.moving", "MovingObstaclesRule"), options=MovingObstaclesOptions,
             description="refuses straights that drive into enough of a mover's possible courses "
                         "(from the last two scans)")
