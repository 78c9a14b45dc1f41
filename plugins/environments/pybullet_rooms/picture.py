"""The pybullet room as a top-down scene (drawn by ``safeembodai_plugins.environments.topdown``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from safeembodai_core.models import Outcome, Pose

from ..topdown import MARGIN_PX, SIZE_PX, TopDownScene, draw_topdown
from .options import CAN_RADIUS_MM
from .scene import WALL_THICKNESS_MM

if TYPE_CHECKING:
    from .world import PybulletRoom

__all__ = ["MARGIN_PX", "SIZE_PX", "draw_trajectory"]


def draw_trajectory(env: "PybulletRoom", poses: list[Pose], outcome: Outcome | None) -> bytes:
    """PNG bytes of the room with ``poses`` (the robot's path) and ``outcome``."""
    o = env.options
    swarm = env.swarm
    has_movers = swarm is not None and len(swarm)
    scene = TopDownScene(
        title=f"{env.kind}  seed {env._seed}", room_mm=o.room_mm, wall_mm=WALL_THICKNESS_MM,
        can_xy=tuple(env.can_xy), can_radius_mm=CAN_RADIUS_MM, reach_mm=o.reach_mm, robot_radius_mm=o.robot_radius_mm,
        obstacles=[(x, y, o.ball_radius_mm) for x, y in env.balls_xy],
        movers_radius_mm=swarm.radius if has_movers else 0.0,
        mover_tracks=np.stack(swarm.track) if has_movers else None,
        collision_xy=env.collision_xy, obstacle_label="soccer ball",
    )
    return draw_topdown(scene, poses, outcome)
