"""Options of the four rooms (``OF``, ``SO``, ``DO``, ``MO``), validated before any physics starts.

Each room has its own model so a key that makes no sense for it is an error: ``OF`` takes no
``balls``, ``SO`` no ``labbots``. Every model forbids unknown keys and checks its ranges, and
the room checks that what it is asked to hold fits: more obstacles than the floor can take
fail here, naming the options at fault, rather than at the first reset. All lengths are
millimetres, angles degrees, times simulated seconds.
"""

from __future__ import annotations

import math

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from safeembodai_core.contracts.descriptions import EnvironmentDescription, EnvironmentOptions

from .movers import MoverFamily, family

CAN_RADIUS_MM = 33.0
SOCCERBALL_RADIUS_MM = 500.0  # pybullet_data's soccerball.urdf at scale 1
#: Share of the floor the placed bodies (each grown by half the passage) may claim. Random
#: sequential placement jams near 55 %; 40 % leaves room to succeed on every seed.
MAX_FLOOR_SHARE = 0.40


class RoomOptions(EnvironmentOptions):
    """Options every room takes (``OF`` takes only these)."""

    room_mm: float = Field(4000.0, ge=1500.0, le=20_000.0, description="inner side of the square room")
    robot_radius_mm: float = Field(170.0, ge=80.0, le=400.0, description="radius of the cylinder robot")
    robot_speed_mm_s: float = Field(200.0, gt=0.0, le=2000.0, description="straight-line speed")
    robot_turn_rate_deg_s: float = Field(60.0, gt=0.0, le=720.0, description="turning speed on the spot")
    reach_mm: float = Field(450.0, gt=0.0, le=5000.0,
                            description="robot-centre to can-centre distance that completes the task (can in view)")
    min_start_distance_mm: float | None = Field(
        None, ge=0.0, description="least robot-to-can distance at the start; default 1200 or 0.6 * room_mm if smaller")
    passage_mm: float | None = Field(None, gt=0.0, le=5000.0,
                                     description="least free gap between placed bodies; default robot diameter + 40")
    max_sim_time_s: float = Field(100.0, gt=0.0, le=100_000.0, description="simulated-time limit (the paper's 100 s)")
    think_time_s: float = Field(0.0, ge=0.0, le=600.0,
                                description="simulated seconds the world runs while the LLM decides, once per step")
    think_time_per_call: bool = Field(
        False, description="charge think_time_s for every LLM call, each retry of a refused answer too "
                           "(default: once per step, whatever the retries)")
    step_mm: float = Field(10.0, ge=1.0, le=50.0, description="motion increment between collision checks")
    step_deg: float = Field(3.0, ge=0.5, le=15.0, description="turn increment between collision checks")
    lidar_beams: int = Field(360, ge=36, le=3600, description="beams per scan, beam k at k*360/N degrees")
    lidar_max_range_mm: float = Field(6000.0, ge=500.0, le=50_000.0, description="no return beyond this: inf")
    camera_width: int = Field(320, ge=16, le=1280, description="image width in pixels (QVGA: 320)")
    camera_height: int = Field(240, ge=12, le=960, description="image height in pixels (QVGA: 240)")
    camera_fov_deg: float = Field(60.0, gt=10.0, lt=170.0, description="horizontal field of view")

    def describe(self) -> EnvironmentDescription:
        return EnvironmentDescription(time_limit_s=self.max_sim_time_s, think_time_s=self.think_time_s,
                                      think_per_call=self.think_time_per_call)

    @property
    def passage(self) -> float:
        return self.passage_mm if self.passage_mm is not None else 2 * self.robot_radius_mm + 40.0

    @property
    def start_distance(self) -> float:
        if self.min_start_distance_mm is not None:
            return self.min_start_distance_mm
        return min(1200.0, 0.6 * self.room_mm)

    @property
    def ball_radius_mm(self) -> float:
        return SOCCERBALL_RADIUS_MM * getattr(self, "ball_scale", 0.0)

    @property
    def ball_count(self) -> int:
        return getattr(self, "balls", 0)

    @property
    def labbot_count(self) -> int:
        return getattr(self, "labbots", 0)

    @model_validator(mode="after")
    def _fits(self) -> "RoomOptions":
        if self.reach_mm <= self.robot_radius_mm + CAN_RADIUS_MM:
            raise ValueError(f"reach_mm={self.reach_mm:g} must exceed robot_radius_mm + can radius "
                             f"({self.robot_radius_mm + CAN_RADIUS_MM:g}): the robot could never get that close")
        apart = self.robot_radius_mm + CAN_RADIUS_MM + self.passage
        if self.min_start_distance_mm is not None and self.min_start_distance_mm < apart:
            # refused rather than raised behind the user's back (bodies need the passage between them)
            raise ValueError(f"min_start_distance_mm={self.min_start_distance_mm:g} is less than the robot and the can "
                             f"need with a passage between them (robot_radius_mm + can radius + passage = {apart:g}); "
                             f"set at least {apart:g}, or a smaller passage_mm")
        if self.start_distance > 0.75 * self.room_mm:
            raise ValueError(f"min_start_distance_mm={self.min_start_distance_mm:g} cannot be met in a room of "
                             f"room_mm={self.room_mm:g}; keep it at most {0.75 * self.room_mm:g}")
        half_gap = self.passage / 2
        need = math.pi * ((self.robot_radius_mm + half_gap) ** 2 + (CAN_RADIUS_MM + half_gap) ** 2
                          + self.ball_count * (self.ball_radius_mm + half_gap) ** 2
                          + self.labbot_count * (getattr(self, "labbot_radius_mm", 0.0) + half_gap) ** 2)
        floor = self.room_mm ** 2
        if need > MAX_FLOOR_SHARE * floor:
            counts = [f"{name}={getattr(self, name)}" for name in ("balls", "labbots") if hasattr(self, name)]
            robot = f"the robot (robot_radius_mm={self.robot_radius_mm:g}) and the can"
            what = " and ".join(counts) if counts else robot
            lower = " or ".join(n.split("=")[0] for n in counts) or "robot_radius_mm"
            raise ValueError(
                f"too many obstacles for the room: {what} with a passage of {self.passage:g} mm between bodies "
                f"need {need / 1e6:.1f} m² but room_mm={self.room_mm:g} allows {MAX_FLOOR_SHARE * floor / 1e6:.1f} m² "
                f"({MAX_FLOOR_SHARE:.0%} of the floor); lower {lower}"
                f" or passage_mm, or raise room_mm")
        return self


class _Balls(BaseModel):
    model_config = ConfigDict(extra="forbid")

    balls: int = Field(4, ge=1, le=60, description="static soccer balls")
    ball_scale: float = Field(0.22, ge=0.05, le=1.0, description="scale of soccerball.urdf (radius 0.5 m at 1.0)")


class _Labbots(BaseModel):
    model_config = ConfigDict(extra="forbid")

    labbots: int = Field(3, ge=1, le=30, description="moving Labbots")
    labbot_radius_mm: float = Field(120.0, ge=50.0, le=400.0, description="radius of a Labbot's cylinder")
    labbot_speed_mm_s: float = Field(150.0, ge=0.0, le=2000.0, description="cruising speed (0 parks them)")
    labbot_turn_rate_deg_s: float = Field(90.0, gt=0.0, le=720.0, description="turning speed when avoiding")
    labbot_wander_deg: float = Field(25.0, ge=0.0, le=180.0,
                                     description="random heading drift, degrees per square-root second")
    labbot_lookahead_mm: float = Field(150.0, ge=0.0, le=2000.0,
                                       description="free space a Labbot keeps ahead before it turns away")
    labbot_sensing: bool = Field(True, description="Labbots steer away from what their five distance sensors read, "
                                                   "the robot included; false: blind Labbots that do not see the robot")
    labbot_sensor_range_mm: float = Field(300.0, ge=10.0, le=3000.0,
                                          description="reach of a Labbot's distance sensors, from its rim")
    labbots_avoid_robot: bool = Field(False, description="Labbots also keep clear of the robot's true position "
                                                         "(no sensing needed)")
    labbot_family: MoverFamily | None = Field(
        None, description="draw each trial's Labbot dynamics from a mover family: 'tuning', 'held_out', 'shipped' "
                          "or a mapping with 'kinds' (replaces the four options it names); none: the scalar options")

    @field_validator("labbot_family", mode="before")
    @classmethod
    def _named_family(cls, value):
        return value if value is None else family(value)

    @model_validator(mode="after")
    def _family_or_scalars(self) -> "_Labbots":
        if self.labbot_family is not None:
            both = [name for name in FAMILY_REPLACES if name in self.model_fields_set]
            if both:
                raise ValueError(f"labbot_family={self.labbot_family.name!r} draws every Labbot's speed, wander, "
                                 f"sensing and yielding; remove {', '.join(both)} (ignored with a family), or "
                                 f"remove labbot_family")
        return self


#: The scalar Labbot options a ``labbot_family`` replaces (setting one alongside it is refused).
FAMILY_REPLACES = ("labbot_speed_mm_s", "labbot_wander_deg", "labbot_sensing", "labbots_avoid_robot")


class OFOptions(RoomOptions):
    """``OF``: obstacle free."""


class SOOptions(_Balls, RoomOptions):
    """``SO``: static obstacles (soccer balls)."""


class DOOptions(_Labbots, RoomOptions):
    """``DO``: dynamic obstacles (Labbots)."""


class MOOptions(_Balls, _Labbots, RoomOptions):
    """``MO``: mixed (soccer balls and Labbots)."""

    balls: int = Field(3, ge=1, le=60, description="static soccer balls")
    labbots: int = Field(2, ge=1, le=30, description="moving Labbots")


ROOMS: dict[str, tuple[type[RoomOptions], str]] = {
    "OF": (OFOptions, "obstacle-free room with a red can (pybullet)"),
    "SO": (SOOptions, "room with a red can and static soccer balls (pybullet)"),
    "DO": (DOOptions, "room with a red can and wandering Labbots (pybullet)"),
    "MO": (MOOptions, "room with a red can, soccer balls and Labbots (pybullet)"),
}
