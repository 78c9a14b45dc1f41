"""The sensors in a :class:`~.scene.Scene`: the robot's LiDAR, front camera and the can's
visibility, and the Labbots' distance sensors.

* LiDAR: ``lidar_beams`` rays in one ``rayTestBatch`` (single-threaded) from the robot's centre
  at :data:`LIDAR_HEIGHT_MM`, beam ``k`` at ``k * 360 / N`` degrees counter-clockwise from the
  heading; ranges in millimetres from the centre, ``inf`` when nothing lies within range (read
  from Bullet's answer without a Python loop per beam).
* Camera: an RGB ``uint8`` image (TinyRenderer, shadows off) from :data:`CAMERA_HEIGHT_MM` just
  in front of the robot, looking along the heading; ``camera_fov_deg`` is the horizontal field.
  A ball wholly outside the field is left out of the rendering (made transparent for it, which
  TinyRenderer skips): it shows no pixel, and its textured mesh is most of a picture's cost. A
  picture already drawn in this process from the same room, view and poses comes from
  :mod:`.picture_cache` (the same pixels).
* Visibility (ground truth, never shown to the LLM): the can is in view when one of three
  points across it, three quarters up, lies inside the camera's frustum and a ray from the
  camera reaches it before anything else, or when the lens is within 10 mm of the can's
  surface (the robot is touching it).
* Labbot distance sensors: five rays per Labbot at :data:`LABBOT_SENSOR_DEG` from its heading,
  from its rim outward at :data:`LIDAR_HEIGHT_MM`, ``labbot_sensor_range_mm`` long, all Labbots
  in one ``rayTestBatch``; they see walls, balls, the can, other Labbots and the robot. A ray
  that passes more than :data:`RAY_SLACK_MM` from every body reads ``inf`` without being cast.

Every read hands Bullet the poses placed since its last one first (:meth:`.scene.Scene.flush`).
The shortcuts change no reading: tests compare each with the reading made without it (issue 51).
"""

from __future__ import annotations

import json
import math
import threading
from operator import itemgetter
from typing import cast

import numpy as np

from . import picture_cache
from .options import CAN_RADIUS_MM, _Labbots
from .scene import CAN_HEIGHT_MM, OBSTACLE_GROUP, ROBOT_GROUP, Scene, _m

LIDAR_HEIGHT_MM = 100.0
CAMERA_HEIGHT_MM = 150.0
CAMERA_AHEAD_MM = 5.0  # in front of the robot's surface, so the body never shows in its own image
TOUCHING_MM = 10.0
_NEAR_M, _FAR_M = 0.02, 30.0
#: A Labbot's sensors, degrees CCW from its heading: ahead, then left/right pairs.
LABBOT_SENSOR_DEG = (0.0, 30.0, -30.0, 60.0, -60.0)
_FIRST, _THIRD = itemgetter(0), itemgetter(2)  # a ray's hit: the body's id, the fraction along the ray
_RIM_GAP_MM = 1.0  # rays start just outside the Labbot's own body
#: A ball this far beyond the camera's field of view (or behind the lens) is left out of the picture.
VIEW_SLACK_MM = 50.0
_HIDDEN_RGBA = (1.0, 1.0, 1.0, 0.0)
#: A Labbot's sensor ray passing farther than this from every body is not cast: it reads nothing
#: (far beyond any ray-cast tolerance, and beyond a ball's section at the rays' height).
RAY_SLACK_MM = 20.0
#: Each room build's options and camera (JSON) by a small number, for the picture cache's keys.
_ROOM_NUMBERS: dict[str, int] = {}
_ROOM_NUMBERS_LOCK = threading.Lock()


class Sensors:
    """Reads the scene from the robot's pose; precomputes what does not change between reads."""

    def __init__(self, scene: Scene) -> None:
        o = scene.o
        self.scene, self.o, self.p = scene, o, scene.p
        self._ball_rgba = {ball: self.p.getVisualShapeData(ball, physicsClientId=scene.client)[0][7]
                           for ball in scene.balls}
        self.beam_angles = np.radians(np.arange(o.lidar_beams) * (360.0 / o.lidar_beams))
        aspect = o.camera_width / o.camera_height
        self.vfov_deg = math.degrees(2 * math.atan(math.tan(math.radians(o.camera_fov_deg / 2)) / aspect))
        self.projection = self.p.computeProjectionMatrixFOV(self.vfov_deg, aspect, _NEAR_M, _FAR_M,
                                                            physicsClientId=scene.client)
        # every body of the client, built with the scene (nothing is added later), for the picture keys
        self._bodies = [self.p.getBodyUniqueId(i, physicsClientId=scene.client)
                        for i in range(self.p.getNumBodies(physicsClientId=scene.client))]
        room = json.dumps([o.model_dump(mode="json"), o.camera_width, o.camera_height, list(self.projection)])
        with _ROOM_NUMBERS_LOCK:
            number = _ROOM_NUMBERS.setdefault(room, len(_ROOM_NUMBERS))
        self._room_key = number.to_bytes(8, "little")

    def lidar(self, xy: np.ndarray, heading_deg: float) -> np.ndarray:
        o = self.o
        self.scene.flush()
        angles = self.beam_angles + math.radians(heading_deg)
        z = _m(LIDAR_HEIGHT_MM)
        start = np.empty((angles.size, 3))
        start[:] = (_m(xy[0]), _m(xy[1]), z)
        reach = _m(o.lidar_max_range_mm)
        end = np.column_stack((start[:, 0] + reach * np.cos(angles), start[:, 1] + reach * np.sin(angles), start[:, 2]))
        hits = self.p.rayTestBatch(start.tolist(), end.tolist(), numThreads=1, collisionFilterMask=OBSTACLE_GROUP,
                                   physicsClientId=self.scene.client)
        hit = np.fromiter(map(_FIRST, hits), dtype=np.int64, count=len(hits)) >= 0
        fraction = np.where(hit, np.fromiter(map(_THIRD, hits), dtype=float, count=len(hits)), np.inf)
        return fraction * o.lidar_max_range_mm

    def camera_pose(self, xy: np.ndarray, heading_deg: float) -> tuple[np.ndarray, np.ndarray]:
        """Camera position and unit view direction (metres, world frame)."""
        rad = math.radians(heading_deg)
        forward = np.array([math.cos(rad), math.sin(rad), 0.0])
        offset = self.o.robot_radius_mm + CAMERA_AHEAD_MM
        eye = np.array([_m(xy[0] + offset * forward[0]), _m(xy[1] + offset * forward[1]), _m(CAMERA_HEIGHT_MM)])
        return eye, forward

    def camera(self, xy: np.ndarray, heading_deg: float) -> np.ndarray:
        o, p, client = self.o, self.p, self.scene.client
        self.scene.flush()
        eye, forward = self.camera_pose(xy, heading_deg)
        hidden = self.balls_out_of_view(xy, heading_deg)
        pictures = picture_cache.PICTURES
        key = self.picture_key(eye, forward, hidden) if pictures.enabled else None
        if key is not None:
            kept = pictures.get(key)
            if kept is not None:
                return kept
        view = p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), (0.0, 0.0, 1.0), physicsClientId=client)
        for ball in hidden:  # TinyRenderer skips a fully transparent shape: none of its triangles is processed
            p.changeVisualShape(ball, -1, rgbaColor=_HIDDEN_RGBA, physicsClientId=client)
        try:
            _, _, rgba, _, _ = p.getCameraImage(
                o.camera_width, o.camera_height, view, self.projection, shadow=0, renderer=p.ER_TINY_RENDERER,
                flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=client)
        finally:
            for ball in hidden:
                p.changeVisualShape(ball, -1, rgbaColor=self._ball_rgba[ball], physicsClientId=client)
        pixels = np.asarray(rgba, dtype=np.uint8).reshape(o.camera_height, o.camera_width, 4)
        picture = np.ascontiguousarray(pixels[..., :3])
        if key is not None:
            pictures.put(key, picture)
        return picture

    def picture_key(self, eye: np.ndarray, forward: np.ndarray, hidden: list[int]) -> bytes:
        """What the picture from ``eye`` looking along ``forward`` is drawn from, as bytes (see
        :mod:`.picture_cache`): the room as built, the balls left out, the view, and the position and
        orientation of every body as Bullet holds them (call after :meth:`.scene.Scene.flush`)."""
        p, client = self.p, self.scene.client
        numbers = [*eye.tolist(), *forward.tolist()]
        for body in self._bodies:
            position, orientation = p.getBasePositionAndOrientation(body, physicsClientId=client)
            numbers += position
            numbers += orientation
        return b"".join((self._room_key, len(hidden).to_bytes(4, "little"), np.array(hidden, dtype=np.int64).tobytes(),
                         np.array(numbers, dtype=np.float64).tobytes()))

    def balls_out_of_view(self, xy: np.ndarray, heading_deg: float) -> list[int]:
        """The balls wholly outside the camera's view from this pose, by :data:`VIEW_SLACK_MM` at
        least: beyond one of the two side planes of its field (vertical planes through the lens: the
        camera looks level), or behind the lens. They show no pixel, and rendering their textured
        meshes is most of a picture's cost in ``SO`` and ``MO``: :meth:`camera` leaves them out."""
        balls = self.scene.balls_xy
        if not len(balls):
            return []
        rad, half = math.radians(heading_deg), math.radians(self.o.camera_fov_deg / 2)
        forward = np.array([math.cos(rad), math.sin(rad)])
        left = np.array([-forward[1], forward[0]])
        eye = np.asarray(xy, dtype=float)[:2] + (self.o.robot_radius_mm + CAMERA_AHEAD_MM) * forward
        outward = np.array([-math.sin(half) * forward + math.cos(half) * left,  # the left plane's outer side
                            -math.sin(half) * forward - math.cos(half) * left,  # the right plane's
                            -forward])  # behind the lens
        beyond = (balls - eye) @ outward.T > self.o.ball_radius_mm + VIEW_SLACK_MM  # (balls, planes)
        return [ball for ball, out in zip(self.scene.balls, beyond.any(axis=1).tolist()) if out]

    def can_in_view(self, xy: np.ndarray, heading_deg: float, can_xy: np.ndarray) -> bool:
        eye, forward = self.camera_pose(xy, heading_deg)
        to_can = np.array([_m(can_xy[0]), _m(can_xy[1])]) - eye[:2]
        across = np.array([-to_can[1], to_can[0]]) / max(float(np.hypot(*to_can)), 1e-9)
        z = _m(0.75 * CAN_HEIGHT_MM)
        targets = [np.array([_m(can_xy[0]), _m(can_xy[1]), z]) + np.append(across * _m(s * 0.8 * CAN_RADIUS_MM), 0.0)
                   for s in (0.0, -1.0, 1.0)]
        half_h, half_v = math.radians(self.o.camera_fov_deg / 2), math.radians(self.vfov_deg / 2)
        heading = math.atan2(forward[1], forward[0])
        if float(np.hypot(*to_can)) <= _m(CAN_RADIUS_MM + TOUCHING_MM):
            return True  # the robot touches the can: it fills the lens (rays from inside it never hit it)
        framed = []
        for target in targets:
            d = target - eye
            yaw = (math.atan2(d[1], d[0]) - heading + math.pi) % (2 * math.pi) - math.pi
            ahead = math.hypot(d[0], d[1]) * math.cos(yaw)
            if ahead <= 0 or abs(yaw) > half_h:
                continue
            # pinhole frustum: the vertical angle is taken against the depth along the optical axis
            if abs(math.atan2(d[2], ahead)) > half_v:
                continue
            framed.append(target)
        if not framed:
            return False
        self.scene.flush()
        hits = self.p.rayTestBatch([eye.tolist()] * len(framed), [t.tolist() for t in framed], numThreads=1,
                                   collisionFilterMask=OBSTACLE_GROUP, physicsClientId=self.scene.client)
        return any(hit[0] == self.scene.can for hit in hits)


class LabbotRangeSensors:
    """The Labbots' distance sensors: ``sensors(xy, headings_deg, robot_xy)`` -> (L, 5) mm.

    Places the robot and the Labbots where they are asked to be (the world re-places every body
    before its own contact checks) and returns, per Labbot and sensor, the free distance from
    the Labbot's rim to the first body, ``inf`` when none lies within ``labbot_sensor_range_mm``.
    Only the rays that pass within :data:`RAY_SLACK_MM` of a body are cast (most pass nowhere
    near one, and read ``inf`` as Bullet would); those are cast exactly as before.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene, self.p = scene, scene.p
        self.offsets = np.radians(LABBOT_SENSOR_DEG)
        labbots = cast(_Labbots, scene.o)  # built only for a room with Labbots: its options have their fields
        self.rim = labbots.labbot_radius_mm + _RIM_GAP_MM
        self.reach = labbots.labbot_sensor_range_mm - _RIM_GAP_MM
        self.labbot_radius = labbots.labbot_radius_mm
        self._offsets = self.offsets.tolist()

    def __call__(self, xy: np.ndarray, headings_deg: np.ndarray, robot_xy: np.ndarray) -> np.ndarray:
        scene = self.scene
        scene.place_robot(robot_xy, 0.0)  # a cylinder: its heading changes nothing a ray sees
        scene.place_labbots(xy, headings_deg)
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        headings_deg = np.asarray(headings_deg, dtype=float).reshape(-1)
        free = np.full(len(xy) * len(self.offsets), np.inf)
        near = self._may_hit(xy.tolist(), headings_deg.tolist(), (float(robot_xy[0]), float(robot_xy[1])))
        if near:  # only the rays that may reach a body go to Bullet, cast as ever; the others read nothing
            angles = (np.radians(headings_deg)[:, None] + self.offsets[None, :]).reshape(-1)
            centres = np.repeat(xy, len(self.offsets), axis=0)
            unit = np.column_stack((np.cos(angles), np.sin(angles)))
            z = np.full((len(angles), 1), LIDAR_HEIGHT_MM)
            start = np.hstack((centres + self.rim * unit, z))[near] / 1000.0
            end = np.hstack((centres + (self.rim + self.reach) * unit, z))[near] / 1000.0
            scene.flush()
            hits = self.p.rayTestBatch(start.tolist(), end.tolist(), numThreads=1,
                                       collisionFilterMask=OBSTACLE_GROUP | ROBOT_GROUP, physicsClientId=scene.client)
            free[near] = [_RIM_GAP_MM + hit[2] * self.reach if hit[0] >= 0 else np.inf for hit in hits]
        return free.reshape(len(xy), len(self.offsets))

    def _may_hit(self, labbots: list[list[float]], headings_deg: list[float],
                 robot: tuple[float, float]) -> list[int]:
        """The rays (index: Labbot * sensors + sensor) that may reach a body; every other ray passes
        more than :data:`RAY_SLACK_MM` from each wall's inner face and each round body's full radius
        (the can, the balls, the robot and the other Labbots: their footprints, whatever their
        heights), so Bullet would find it no hit. Plain floats: a handful of bodies and rays."""
        statics = self.scene.statics()
        count = len(self.offsets)
        if statics is None:  # nothing placed yet: every ray goes to Bullet
            return list(range(len(labbots) * count))
        slack, room, rim, reach = RAY_SLACK_MM, self.scene.o.room_mm, self.rim, self.reach
        fan = rim + reach + slack  # no ray of a Labbot leaves this disc around its centre, slack included
        bodies = [tuple(row) for row in statics.tolist()]
        bodies.append((robot[0], robot[1], self.scene.o.robot_radius_mm))
        bodies += [(x, y, self.labbot_radius) for x, y in labbots]
        own_at = len(bodies) - len(labbots)
        near: list[int] = []
        for index, ((cx, cy), heading) in enumerate(zip(labbots, headings_deg)):
            walls = cx < fan or cy < fan or room - cx < fan or room - cy < fan
            close = [(bx, by, radius + slack) for k, (bx, by, radius) in enumerate(bodies)
                     if k != own_at + index and math.hypot(bx - cx, by - cy) - radius < fan]
            if not walls and not close:
                continue
            rad = math.radians(heading)
            for sensor, offset in enumerate(self._offsets):
                ux, uy = math.cos(rad + offset), math.sin(rad + offset)
                ax, ay = cx + rim * ux, cy + rim * uy
                ex, ey = ax + reach * ux, ay + reach * uy
                hit = walls and (min(ax, ex) < slack or min(ay, ey) < slack
                                 or max(ax, ex) > room - slack or max(ay, ey) > room - slack)
                for bx, by, within in close:
                    if hit:
                        break
                    along = min(max((bx - ax) * ux + (by - ay) * uy, 0.0), reach)
                    hit = math.hypot(bx - ax - along * ux, by - ay - along * uy) < within
                if hit:
                    near.append(index * count + sensor)
        return near
