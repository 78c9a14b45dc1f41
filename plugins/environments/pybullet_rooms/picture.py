"""The pybullet room as a top-down scene (drawn by ``safeembodai_plugins.environments.topdown``).

Handed what it draws by ``PybulletRoom.trajectory_png``: it knows the room's options and parts,
not the environment class (which imports this module).
"""

from __future__ import annotations

import numpy as np

from safeembodai_core.models import Outcome, Pose

from ..topdown import MARGIN_PX, SIZE_PX, TopDownScene, draw_topdown
from .labbots import LabbotSwarm
from .options import CAN_RADIUS_MM, RoomOptions
from .scene import WALL_THICKNESS_MM

__all__ = ["MARGIN_PX", "SIZE_PX", "draw_trajectory"]


def draw_trajectory(title: str, o: RoomOptions, can_xy, balls_xy, swarm: LabbotSwarm | None, collision_xy,
                    poses: list[Pose], outcome: Outcome | None) -> bytes:
    """PNG bytes of the room (``o``; the can, the balls, the Labbots' tracks, where the robot
    collided) titled ``title``, with ``poses`` (the robot's path) and ``outcome``."""
    movers = swarm if swarm is not None and len(swarm) else None
    scene = TopDownScene(
        title=title, room_mm=o.room_mm, wall_mm=WALL_THICKNESS_MM,
        can_xy=tuple(can_xy), can_radius_mm=CAN_RADIUS_MM, reach_mm=o.reach_mm, robot_radius_mm=o.robot_radius_mm,
        obstacles=[(x, y, o.ball_radius_mm) for x, y in balls_xy],
        movers_radius_mm=movers.radius if movers is not None else 0.0,
        mover_tracks=np.stack(movers.track) if movers is not None else None,
        collision_xy=collision_xy, obstacle_label="soccer ball",
    )
    return draw_topdown(scene, poses, outcome)
