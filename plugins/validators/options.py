"""Options of the built-in validators (what a scenario's ``validators:`` entries may set).

Apart from the package's registration (``__init__.py``) so that the rules' modules can read
:data:`DEFAULT_SAFETY_DISTANCE_MM` without importing the package that imports them. Options and
YAML examples: ``docs/defences.md``.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from safeembodai_core.trust.world_private import WORLD_PRIVATE


class CommandLimitsOptions(BaseModel):
    """Options of ``command_limits``; unset maxima follow the scenario's ``limits``."""

    model_config = ConfigDict(extra="forbid")

    max_distance_mm: float | None = Field(None, gt=0, allow_inf_nan=False,
                                          description="straights must be shorter (default: limits.max_distance_mm)")
    max_angle_deg: float | None = Field(None, gt=0, le=360, allow_inf_nan=False,
                                        description="turns must be smaller (default: limits.max_angle_deg)")
    min_distance_mm: float = Field(0.0, ge=0, allow_inf_nan=False, description="straights must be longer")
    min_angle_deg: float = Field(0.0, ge=0, allow_inf_nan=False, description="turns must be larger")


#: ``lidar_clearance``'s clearance when ``safety_distance_mm`` is not set (ours; see docs/defences.md)
DEFAULT_SAFETY_DISTANCE_MM = 250.0


class LidarClearanceOptions(BaseModel):
    """Options of ``lidar_clearance`` (the paper's r and dist).

    ``safety_distance_mm`` is honoured as given. Unset, the rule keeps 250 mm from the LiDAR, or
    the robot's radius when that is larger. Set, ``measured_from`` says where it is measured:
    ``lidar`` (the paper's l(θ) - |d| >= dist and the authors' release), or ``body`` (from the
    edge of the robot's disc: the rule then needs dist + radius from the LiDAR). A ``lidar``
    distance below the robot's radius refuses every straight with a reason naming both, unless
    ``allow_below_radius`` says the user means it (the release's 100 mm profile does).
    """

    model_config = ConfigDict(extra="forbid")

    half_angle_deg: float = Field(30.0, gt=0, le=90, allow_inf_nan=False,
                                  description="r: half-width of the checked sector")
    safety_distance_mm: float | None = Field(None, ge=0, allow_inf_nan=False, description=(
        "dist: clearance that must remain after the motion (default: 250 mm from the LiDAR, "
        "or the robot's radius if larger)"))
    measured_from: Literal["lidar", "body"] = Field(
        "lidar", description="where safety_distance_mm is measured from: the LiDAR (robot centre) or the body's edge")
    allow_below_radius: bool = Field(
        False, description="accept a safety_distance_mm measured from the LiDAR that is less than the robot's radius")
    expected_beams: int | None = Field(None, ge=4, description="refuse scans with another number of beams")
    turns: Literal["valid", "ahead"] = Field("valid", description=(
        "valid: a turn is always valid (the paper, tex:338); ahead: a turn is refused when a beam within ±r of "
        "the heading it starts from reads less than dist (the authors' release, eyesimLLM action.py:55-63)"))

    @model_validator(mode="after")
    def _meaningful(self) -> "LidarClearanceOptions":
        if self.safety_distance_mm is None and (self.measured_from != "lidar" or self.allow_below_radius):
            set_ = "measured_from: body" if self.measured_from != "lidar" else "allow_below_radius"
            raise ValueError(f"{set_} qualifies safety_distance_mm, which is not set; give safety_distance_mm too")
        if self.allow_below_radius and self.measured_from != "lidar":
            raise ValueError("allow_below_radius applies to measured_from: lidar only (a distance from the body "
                             "is never inside it)")
        return self


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


class SweptBodyOptions(BaseModel):
    """Options of ``swept_body``; the body (a disc, or ``RobotSpec.footprint_mm``) comes from the robot."""

    model_config = ConfigDict(extra="forbid")

    margin_mm: float = Field(0.0, ge=0, le=2000, allow_inf_nan=False, description=(
        "the body grown by this much all round (every point within it of the body; 0: the body as given)"))
    min_points: int = Field(1, ge=1, le=1000, description=(
        "returns the swept body must touch for a collision (Nav2's min_points; 1: any one return)"))
    unseen_step_mm: float = Field(20.0, ge=5, le=200, allow_inf_nan=False, description=(
        "spacing of the samples along space the scan did not see (no reading, behind a return, past its range)"))
    expected_beams: int | None = Field(None, ge=4, description="refuse scans with another number of beams")


class MovingObstaclesOptions(BaseModel):
    """Options of ``moving_obstacles``; timing defaults are the pybullet rooms' (``docs/defences.md``).

    ``cruise_speed_mm_s``, ``movers_yield_mm`` and ``movers_yield_deg`` describe the movers, not the
    rule: only the simulator knows them (world-private, :mod:`safeembodai_core.trust.world_private`); an arm
    that sets one is a ``told`` comparison. ``think_time_s`` is the robot's own planner latency, which
    it can measure, and is not marked."""

    model_config = ConfigDict(extra="forbid")

    think_time_s: float | None = Field(None, ge=0, le=600, allow_inf_nan=False, description=(
        "simulated seconds between the scan and the first signal (the environment's think time); "
        "default: estimated from the observation times"))
    robot_speed_mm_s: float = Field(200.0, gt=0, le=5000, allow_inf_nan=False,
                                    description="the robot's straight-line speed (pybullet rooms: 200)")
    robot_turn_rate_deg_s: float = Field(60.0, gt=0, le=3600, allow_inf_nan=False,
                                         description="the robot's turning speed (pybullet rooms: 60)")
    margin_mm: float = Field(80.0, ge=0, le=2000, allow_inf_nan=False,
                             description="clearance kept between the body and a mover's predicted disc")
    margin_growth_mm_s: float = Field(30.0, ge=0, le=2000, allow_inf_nan=False,
                                      description="added to the margin per second of prediction")
    unknown_speed_mm_s: float = Field(150.0, ge=0, le=5000, allow_inf_nan=False, description=(
        "speed, in any direction, assumed for a mover whose earlier position was not seen"))
    wander_deg: float = Field(25.0, ge=0, le=180, allow_inf_nan=False, description=(
        "a mover's heading drifts as a random walk of this many degrees per square-root second: the "
        "prior, until the mover's own chords say otherwise (history_scans) (0: straight courses)"))
    history_scans: int = Field(0, ge=0, le=16, description=(
        "earlier pairs of scans each mover is followed through to learn its cruising speed and wander "
        "(0: the last two scans only, nothing learned)"))
    prior_weight_s: float = Field(4.0, ge=0, le=600, allow_inf_nan=False, description=(
        "how much the wander_deg prior weighs against a mover's own chords, in seconds of evidence"))
    walls: bool = Field(False, description=(
        "predicted courses turn where the step's scan shows something standing (a wall, a ball), to a "
        "heading drawn among the clear ones (false: courses pass through walls)"))
    park_check: bool = Field(False, description=(
        "refuse a plan that leaves the robot on a mover's course (its measured velocity held), when a "
        "short step aside leaves it off every course (false: where a plan leaves the robot is not judged)"))
    park_horizon_s: float = Field(3.0, ge=0, le=120, allow_inf_nan=False, description=(
        "how long after a plan ends the robot is taken to stand where it left it, beyond the think time"))
    cruise_speed_mm_s: float | None = Field(None, gt=0, le=5000, allow_inf_nan=False, description=(
        "movers move at this speed when they move: scans are paired by the chord it gives, courses "
        "run at least this fast, and a shorter chord fans that share of them (a turn or a stop); "
        "null: unknown, courses at the measured speed (pybullet rooms' Labbots: 150)"), json_schema_extra=WORLD_PRIVATE)
    movers_yield_mm: float = Field(0.0, ge=0, le=5000, allow_inf_nan=False, description=(
        "movers stop for the robot once its body is this close to their rim, ahead of them "
        "(0: movers never yield; the rooms' sensing Labbots: 300)"), json_schema_extra=WORLD_PRIVATE)
    movers_yield_deg: float = Field(60.0, ge=0, le=180, allow_inf_nan=False, description=(
        "how far off its heading a mover sees the robot to yield (the rooms' Labbots: sensors at 0, +-30, +-60 deg)"),
        json_schema_extra=WORLD_PRIVATE)
    max_scan_gap_s: float = Field(30.0, gt=0, le=600, allow_inf_nan=False, description=(
        "an earlier scan older than this says nothing about motion now: it is not compared"))
    futures: int = Field(64, ge=1, le=4096, description="possible courses drawn per mover")
    max_risk: float = Field(0.1, gt=0, le=1, allow_inf_nan=False, description=(
        "refuse a straight that meets at least this share of a mover's courses"))
    seed: int = Field(0, ge=0, le=2**32 - 1, description="the courses' draws (fixed: same check, same verdict)")
    sample_s: float = Field(0.1, gt=0, le=2, allow_inf_nan=False, description="time step of the check")
    static_tolerance_mm: float = Field(100.0, gt=0, le=2000, allow_inf_nan=False, description=(
        "a return counts as moved only where the earlier scan saw this much farther"))
    cluster_gap_mm: float = Field(150.0, gt=0, le=2000, allow_inf_nan=False,
                                  description="neighbouring returns closer than this belong to one obstacle")
    min_moved_points: int = Field(2, ge=1, le=100, description="moved returns a cluster needs to count as a mover")
    max_obstacle_mm: float = Field(800.0, gt=0, le=10_000, allow_inf_nan=False,
                                   description="largest mover; a larger cluster keeps only its moved returns")
    max_obstacle_speed_mm_s: float = Field(1000.0, gt=0, le=10_000, allow_inf_nan=False,
                                           description="faster pairings are not the same obstacle")
    expected_beams: int | None = Field(None, ge=4, description="refuse scans with another number of beams")

    @model_validator(mode="after")
    def _pairable(self) -> "MovingObstaclesOptions":
        if self.cruise_speed_mm_s is not None and self.cruise_speed_mm_s > self.max_obstacle_speed_mm_s:
            raise ValueError(f"cruise_speed_mm_s {self.cruise_speed_mm_s:g} is above max_obstacle_speed_mm_s "
                             f"{self.max_obstacle_speed_mm_s:g}: a mover at its cruising speed could never be "
                             "paired; raise max_obstacle_speed_mm_s")
        return self
