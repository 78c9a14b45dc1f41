"""The bodies of a room in one pybullet physics client.

One client per environment (DIRECT mode), built once with every body the options ask for and
re-posed on each reset: reconnecting per trial leaks memory, and re-posing keeps the body ids
(and so the render order) identical from trial to trial. Units inside pybullet are metres;
everything this module exposes is in millimetres.

The robot is a dynamic body (mass > 0: Bullet skips contacts between two static bodies) that
is never simulated, only placed; :meth:`Scene.contacts` runs the collision detection and
reports the bodies the robot penetrates. The robot sits in its own collision group so the
LiDAR and visibility rays, which use only the obstacle group, pass through it.
"""

from __future__ import annotations

import math
import os
from typing import Any, cast

import numpy as np

from .options import CAN_RADIUS_MM, RoomOptions, _Balls, _Labbots
from .quiet import import_pybullet, silenced

WALL_HEIGHT_MM = 500.0
WALL_THICKNESS_MM = 100.0
ROBOT_HEIGHT_MM = 200.0
CAN_HEIGHT_MM = 120.0
LABBOT_HEIGHT_MM = 200.0
OBSTACLE_GROUP = 1
ROBOT_GROUP = 4
#: A contact counts when the bodies overlap by more than this (Bullet also reports near misses).
PENETRATION_MM = 0.0

WALL_RGBA = (0.80, 0.78, 0.72, 1.0)
FLOOR_RGBA = (0.45, 0.45, 0.45, 1.0)
ROBOT_RGBA = (0.15, 0.15, 0.15, 1.0)
CAN_RGBA = (0.85, 0.05, 0.05, 1.0)
LABBOT_RGBA = (0.15, 0.35, 0.75, 1.0)


def _m(mm: float) -> float:
    return mm / 1000.0


def yaw_quaternion(heading_deg: float) -> tuple[float, float, float, float]:
    half = math.radians(heading_deg) / 2
    return (0.0, 0.0, math.sin(half), math.cos(half))


class Scene:
    """Walls, floor, robot, can, soccer balls and Labbots in a private pybullet client."""

    def __init__(self, options: RoomOptions) -> None:
        self.o = options
        self.p, data_path = import_pybullet()
        with silenced():
            self.client = self.p.connect(self.p.DIRECT)
            try:
                self._build(data_path)
            except Exception:
                self.p.disconnect(physicsClientId=self.client)
                raise
        self.closed = False

    def _call(self, name: str, *args: Any, **kwargs: Any) -> Any:
        return getattr(self.p, name)(*args, physicsClientId=self.client, **kwargs)

    def _body(self, collision: int, visual: int, mass: float = 0.0, z_mm: float = 0.0) -> int:
        return self._call("createMultiBody", baseMass=mass, baseCollisionShapeIndex=collision,
                          baseVisualShapeIndex=visual, basePosition=(0.0, 0.0, _m(z_mm)))

    def _cylinder(self, radius_mm: float, height_mm: float, rgba, mass: float = 0.0) -> int:
        collision = self._call("createCollisionShape", self.p.GEOM_CYLINDER, radius=_m(radius_mm), height=_m(height_mm))
        visual = self._call("createVisualShape", self.p.GEOM_CYLINDER, radius=_m(radius_mm), length=_m(height_mm),
                            rgbaColor=rgba)
        return self._body(collision, visual, mass, height_mm / 2)

    def _build(self, data_path: str) -> None:
        o, room = self.o, self.o.room_mm
        outer = room / 2 + WALL_THICKNESS_MM
        floor = self._call("createVisualShape", self.p.GEOM_BOX, halfExtents=(_m(outer), _m(outer), 0.005),
                           rgbaColor=FLOOR_RGBA)
        self.floor = self._call("createMultiBody", baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=floor,
                                basePosition=(_m(room / 2), _m(room / 2), -0.005))
        self.walls = []
        half_t, half_h = WALL_THICKNESS_MM / 2, WALL_HEIGHT_MM / 2
        for cx, cy, hx, hy in ((room / 2, -half_t, outer, half_t), (room / 2, room + half_t, outer, half_t),
                               (-half_t, room / 2, half_t, outer), (room + half_t, room / 2, half_t, outer)):
            extents = (_m(hx), _m(hy), _m(half_h))
            collision = self._call("createCollisionShape", self.p.GEOM_BOX, halfExtents=extents)
            visual = self._call("createVisualShape", self.p.GEOM_BOX, halfExtents=extents, rgbaColor=WALL_RGBA)
            wall = self._body(collision, visual, 0.0, half_h)
            self._call("resetBasePositionAndOrientation", wall, (_m(cx), _m(cy), _m(half_h)), (0, 0, 0, 1))
            self.walls.append(wall)
        self.robot = self._cylinder(o.robot_radius_mm, ROBOT_HEIGHT_MM, ROBOT_RGBA, mass=1.0)
        self.can = self._cylinder(CAN_RADIUS_MM, CAN_HEIGHT_MM, CAN_RGBA)
        ball_file = os.path.join(data_path, "soccerball.urdf")
        # read only where the room has balls (Labbots): its options then have their fields
        balls, labbots = cast(_Balls, o), cast(_Labbots, o)
        self.balls = [self._call("loadURDF", ball_file, basePosition=(0.0, 0.0, _m(o.ball_radius_mm)),
                                 globalScaling=balls.ball_scale, useFixedBase=True) for _ in range(o.ball_count)]
        self.labbots = [self._cylinder(labbots.labbot_radius_mm, LABBOT_HEIGHT_MM, LABBOT_RGBA)
                        for _ in range(o.labbot_count)]
        for body in self.walls + [self.can] + self.balls + self.labbots:
            self._call("setCollisionFilterGroupMask", body, -1, OBSTACLE_GROUP, OBSTACLE_GROUP | ROBOT_GROUP)
        self._call("setCollisionFilterGroupMask", self.robot, -1, ROBOT_GROUP, OBSTACLE_GROUP)
        self.names = {wall: "a wall" for wall in self.walls}
        self.names.update({self.can: "the can"})
        self.names.update({ball: f"soccer ball {k + 1}" for k, ball in enumerate(self.balls)})
        self.names.update({bot: f"Labbot {k + 1}" for k, bot in enumerate(self.labbots)})
        self.kinds = {wall: "wall" for wall in self.walls}
        self.kinds.update({self.can: "can"})
        self.kinds.update({ball: "ball" for ball in self.balls})
        self.kinds.update({bot: "labbot" for bot in self.labbots})

    # -- placing ------------------------------------------------------------------------------

    def place(self, body: int, xy: np.ndarray, z_mm: float, heading_deg: float = 0.0) -> None:
        self._call("resetBasePositionAndOrientation", body, (_m(xy[0]), _m(xy[1]), _m(z_mm)),
                   yaw_quaternion(heading_deg))

    def place_robot(self, xy: np.ndarray, heading_deg: float) -> None:
        self.place(self.robot, xy, ROBOT_HEIGHT_MM / 2, heading_deg)

    def place_labbots(self, xy: np.ndarray, headings_deg: np.ndarray) -> None:
        for body, point, heading in zip(self.labbots, xy, headings_deg):
            self.place(body, point, LABBOT_HEIGHT_MM / 2, float(heading))

    def place_statics(self, can_xy: np.ndarray, balls_xy: np.ndarray) -> None:
        self.place(self.can, can_xy, CAN_HEIGHT_MM / 2)
        for body, point in zip(self.balls, balls_xy):
            self.place(body, point, self.o.ball_radius_mm)

    # -- contact ------------------------------------------------------------------------------

    def contacts(self) -> set[int]:
        """Bodies the robot overlaps now (after re-running collision detection)."""
        self._call("performCollisionDetection")
        points = self._call("getContactPoints", bodyA=self.robot)
        return {point[2] for point in points if point[8] * 1000.0 < -PENETRATION_MM}

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            with silenced():
                self.p.disconnect(physicsClientId=self.client)
