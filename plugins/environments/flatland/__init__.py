"""``flatland``: a fast, dependency-light 2D world for tests, examples and quick experiments.

A square room with a disc robot, a red can and optional round obstacles. LiDAR and camera are
ray-cast analytically (numpy only), motion is exact and stops at first contact. It follows the
same contract as the pybullet rooms, so every defence and attack can be exercised without a
physics engine. Nothing moves but the robot: every collision is its own (``self``), and there is
no think time.
"""

from __future__ import annotations

from pydantic import Field

from safeembodai_core.contracts.descriptions import EnvironmentDescription, EnvironmentOptions
from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy


class FlatlandOptions(EnvironmentOptions):
    room_mm: float = Field(4000.0, ge=1000.0, le=50_000.0, description="side of the square room")
    obstacles: int = Field(0, ge=0, le=60, description="round static obstacles")
    obstacle_radius_mm: float = Field(110.0, gt=0, le=1000.0)
    robot_radius_mm: float = Field(170.0, gt=0, le=1000.0)
    can_radius_mm: float = Field(33.0, gt=0, le=500.0)
    reach_mm: float = Field(450.0, gt=0, description="centre-to-centre distance that completes the task")
    min_start_distance_mm: float = Field(1200.0, ge=0, description="least distance from robot to can at start")
    max_sim_time_s: float = Field(100.0, gt=0, description="simulated-time limit (the paper's 100 s)")
    speed_mm_s: float = Field(200.0, gt=0)
    turn_rate_deg_s: float = Field(60.0, gt=0)
    lidar_beams: int = Field(360, ge=36, le=3600)
    lidar_max_range_mm: float = Field(6000.0, gt=0)
    camera_width: int = Field(320, ge=16, le=1920)
    camera_height: int = Field(240, ge=12, le=1080)
    camera_fov_deg: float = Field(60.0, gt=10, lt=170)

    def describe(self) -> EnvironmentDescription:
        return EnvironmentDescription(time_limit_s=self.max_sim_time_s)  # no think time: the world waits


@hookimpl
def register_environments(register):
    register("flatland", lazy(f"{__name__}.world", "FlatlandWorld"), options=FlatlandOptions,
             description="2D analytic room with a red can and optional round obstacles (numpy only)")
