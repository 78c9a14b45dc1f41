"""The bodies of a room in one pybullet physics client.

One client per environment (DIRECT mode), built once with every body the options ask for and
re-posed on each reset: reconnecting per trial leaks memory, and re-posing keeps the body ids
(and so the render order) identical from trial to trial. Units inside pybullet are metres;
everything this module exposes is in millimetres.

The robot is a dynamic body (mass > 0: Bullet skips contacts between two static bodies) that
is never simulated, only placed; :meth:`Scene.contacts` runs the collision detection and
reports the bodies the robot penetrates. The robot sits in its own collision group so the
LiDAR and visibility rays, which use only the obstacle group, pass through it.

Most checks find the robot far from everything: :meth:`Scene.contacts` keeps where it placed
each body and answers "nothing" without asking Bullet when every body's surface lies more than
:data:`CLEAR_MM` from the robot's *and* Bullet's last detection was made that far from everything
too. That answer is Bullet's own: a contact needs overlapping bodies, and a detection made that
far apart leaves none of the contact points Bullet keeps between checks (it drops every point
beyond its contact-breaking threshold, 20 mm at most), so the next detection Bullet does make
starts from the same empty state as if the skipped ones had run. Placements, likewise, reach
Bullet when it is next read (:meth:`Scene.flush`), each body at its last pose: a pose no read
sees is never sent (issue 51).
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
#: Surfaces farther apart than this cannot touch, nor leave a contact point Bullet keeps (its
#: contact-breaking threshold is 20 mm at most): :meth:`Scene.contacts` need not ask Bullet.
CLEAR_MM = 50.0

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
        # where each body was last placed (mm), for the contact checks' shortcut
        self._reset_pose = self.p.resetBasePositionAndOrientation
        self.robot_xy = (math.inf, math.inf)
        self.labbots_xy: list[tuple[float, float]] = [(math.inf, math.inf) for _ in self.labbots]
        self._statics: list[tuple[float, float, float]] = []  # can and balls: x, y, radius (mm)
        self._statics_array: np.ndarray | None = None
        self.balls_xy = np.zeros((0, 2))  # as placed (mm)
        self._clean = False  # Bullet's last detection was made with everything farther than CLEAR_MM
        self._pending: dict[int, tuple[float, float, float, float]] = {}  # body: x, y, z (m), heading (deg)

    # -- placing ------------------------------------------------------------------------------
    # A placement is kept until Bullet is next read (:meth:`flush`): a pose that no read sees (the
    # Labbots re-placed a tick later, nothing asked meanwhile) never costs a call into Bullet.

    def place(self, body: int, xy: np.ndarray, z_mm: float, heading_deg: float = 0.0) -> None:
        self._pending[body] = (_m(xy[0]), _m(xy[1]), _m(z_mm), heading_deg)

    def place_robot(self, xy: np.ndarray, heading_deg: float) -> None:
        x, y = float(xy[0]), float(xy[1])
        self.robot_xy = (x, y)
        self._pending[self.robot] = (x / 1000.0, y / 1000.0, ROBOT_HEIGHT_MM / 2000.0, heading_deg)

    def place_labbots(self, xy: np.ndarray, headings_deg: np.ndarray) -> None:
        points = np.asarray(xy, dtype=float).reshape(-1, 2).tolist()
        headings = np.asarray(headings_deg, dtype=float).reshape(-1).tolist()
        z, pending, placed = LABBOT_HEIGHT_MM / 2000.0, self._pending, self.labbots_xy
        for index, (body, (x, y), heading) in enumerate(zip(self.labbots, points, headings)):
            pending[body] = (x / 1000.0, y / 1000.0, z, heading)
            placed[index] = (x, y)

    def flush(self) -> None:
        """Hand Bullet the poses placed since its last read: every read of the scene (contacts, rays,
        pictures) calls this first, so Bullet holds each body where it was last placed when read."""
        if self._pending:
            reset, client = self._reset_pose, self.client
            for body, (x, y, z, heading) in self._pending.items():
                reset(body, (x, y, z), yaw_quaternion(heading), physicsClientId=client)
            self._pending.clear()

    def place_statics(self, can_xy: np.ndarray, balls_xy: np.ndarray) -> None:
        self.place(self.can, can_xy, CAN_HEIGHT_MM / 2)
        for body, point in zip(self.balls, balls_xy):
            self.place(body, point, self.o.ball_radius_mm)
        self._statics = [(float(can_xy[0]), float(can_xy[1]), CAN_RADIUS_MM)]
        self._statics += [(float(x), float(y), self.o.ball_radius_mm) for x, y in np.reshape(balls_xy, (-1, 2))]
        self._statics_array = np.array(self._statics, dtype=float).reshape(-1, 3)
        self.balls_xy = self._statics_array[1:, :2]
        self._clean = False  # a new trial: whatever the last one left, the next detection is Bullet's

    def statics(self) -> np.ndarray | None:
        """The can and the balls as placed: (N, 3) rows of x, y, radius (mm); None before they are."""
        return self._statics_array

    # -- contact ------------------------------------------------------------------------------

    def clearance(self) -> float:
        """A lower bound (mm) on the gap between the robot's surface and every other body's, from
        where they were placed: walls (their inner faces), the can, the balls (their full radius) and
        the Labbots; ``-inf`` before the statics are placed (nothing is known: never a shortcut)."""
        if not self._statics:
            return -math.inf
        x, y = self.robot_xy
        r, room = self.o.robot_radius_mm, self.o.room_mm
        gap = min(x, y, room - x, room - y) - r
        for sx, sy, radius in self._statics:
            gap = min(gap, math.hypot(sx - x, sy - y) - radius - r)
        if self.labbots:
            reach = r + cast(_Labbots, self.o).labbot_radius_mm
            for lx, ly in self.labbots_xy:
                gap = min(gap, math.hypot(lx - x, ly - y) - reach)
        return gap

    def contacts(self) -> set[int]:
        """Bodies the robot overlaps now (after re-running collision detection); without asking
        Bullet when everything is more than :data:`CLEAR_MM` away and its last detection was too."""
        clear = self.clearance() > CLEAR_MM
        if clear and self._clean:
            return set()  # what Bullet would say: see the module docstring
        self._clean = clear
        self.flush()
        self._call("performCollisionDetection")
        points = self._call("getContactPoints", bodyA=self.robot)
        return {point[2] for point in points if point[8] * 1000.0 < -PENETRATION_MM}

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            with silenced():
                self.p.disconnect(physicsClientId=self.client)
