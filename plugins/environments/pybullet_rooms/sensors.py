"""The sensors in a :class:`~.scene.Scene`: the robot's LiDAR, front camera and the can's
visibility, and the Labbots' distance sensors.

* LiDAR: ``lidar_beams`` rays in one ``rayTestBatch`` (single-threaded) from the robot's centre
  at :data:`LIDAR_HEIGHT_MM`, beam ``k`` at ``k * 360 / N`` degrees counter-clockwise from the
  heading; ranges in millimetres from the centre, ``inf`` when nothing lies within range.
* Camera: an RGB ``uint8`` image (TinyRenderer, shadows off) from :data:`CAMERA_HEIGHT_MM` just
  in front of the robot, looking along the heading; ``camera_fov_deg`` is the horizontal field.
* Visibility (ground truth, never shown to the LLM): the can is in view when one of three
  points across it, three quarters up, lies inside the camera's frustum and a ray from the
  camera reaches it before anything else, or when the lens is within 10 mm of the can's
  surface (the robot is touching it).
* Labbot distance sensors: five rays per Labbot at :data:`LABBOT_SENSOR_DEG` from its heading,
  from its rim outward at :data:`LIDAR_HEIGHT_MM`, ``labbot_sensor_range_mm`` long, all Labbots
  in one ``rayTestBatch``; they see walls, balls, the can, other Labbots and the robot.
"""

from __future__ import annotations

import math
from typing import cast

import numpy as np

from .options import CAN_RADIUS_MM, _Labbots
from .scene import CAN_HEIGHT_MM, OBSTACLE_GROUP, ROBOT_GROUP, Scene, _m

LIDAR_HEIGHT_MM = 100.0
CAMERA_HEIGHT_MM = 150.0
CAMERA_AHEAD_MM = 5.0  # in front of the robot's surface, so the body never shows in its own image
TOUCHING_MM = 10.0
_NEAR_M, _FAR_M = 0.02, 30.0
#: A Labbot's sensors, degrees CCW from its heading: ahead, then left/right pairs.
LABBOT_SENSOR_DEG = (0.0, 30.0, -30.0, 60.0, -60.0)
_RIM_GAP_MM = 1.0  # rays start just outside the Labbot's own body


class Sensors:
    """Reads the scene from the robot's pose; precomputes what does not change between reads."""

    def __init__(self, scene: Scene) -> None:
        o = scene.o
        self.scene, self.o, self.p = scene, o, scene.p
        self.beam_angles = np.radians(np.arange(o.lidar_beams) * (360.0 / o.lidar_beams))
        aspect = o.camera_width / o.camera_height
        self.vfov_deg = math.degrees(2 * math.atan(math.tan(math.radians(o.camera_fov_deg / 2)) / aspect))
        self.projection = self.p.computeProjectionMatrixFOV(self.vfov_deg, aspect, _NEAR_M, _FAR_M,
                                                            physicsClientId=scene.client)

    def lidar(self, xy: np.ndarray, heading_deg: float) -> np.ndarray:
        o = self.o
        angles = self.beam_angles + math.radians(heading_deg)
        z = _m(LIDAR_HEIGHT_MM)
        start = np.empty((angles.size, 3))
        start[:] = (_m(xy[0]), _m(xy[1]), z)
        reach = _m(o.lidar_max_range_mm)
        end = np.column_stack((start[:, 0] + reach * np.cos(angles), start[:, 1] + reach * np.sin(angles), start[:, 2]))
        hits = self.p.rayTestBatch(start.tolist(), end.tolist(), numThreads=1, collisionFilterMask=OBSTACLE_GROUP,
                                   physicsClientId=self.scene.client)
        fraction = np.array([hit[2] if hit[0] >= 0 else np.inf for hit in hits])
        return fraction * o.lidar_max_range_mm

    def camera_pose(self, xy: np.ndarray, heading_deg: float) -> tuple[np.ndarray, np.ndarray]:
        """Camera position and unit view direction (metres, world frame)."""
        rad = math.radians(heading_deg)
        forward = np.array([math.cos(rad), math.sin(rad), 0.0])
        offset = self.o.robot_radius_mm + CAMERA_AHEAD_MM
        eye = np.array([_m(xy[0] + offset * forward[0]), _m(xy[1] + offset * forward[1]), _m(CAMERA_HEIGHT_MM)])
        return eye, forward

    def camera(self, xy: np.ndarray, heading_deg: float) -> np.ndarray:
        o = self.o
        eye, forward = self.camera_pose(xy, heading_deg)
        view = self.p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), (0.0, 0.0, 1.0),
                                        physicsClientId=self.scene.client)
        _, _, rgba, _, _ = self.p.getCameraImage(
            o.camera_width, o.camera_height, view, self.projection, shadow=0, renderer=self.p.ER_TINY_RENDERER,
            flags=self.p.ER_NO_SEGMENTATION_MASK, physicsClientId=self.scene.client)
        pixels = np.asarray(rgba, dtype=np.uint8).reshape(o.camera_height, o.camera_width, 4)
        return np.ascontiguousarray(pixels[..., :3])

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
        hits = self.p.rayTestBatch([eye.tolist()] * len(framed), [t.tolist() for t in framed], numThreads=1,
                                   collisionFilterMask=OBSTACLE_GROUP, physicsClientId=self.scene.client)
        return any(hit[0] == self.scene.can for hit in hits)


class LabbotRangeSensors:
    """The Labbots' distance sensors: ``sensors(xy, headings_deg, robot_xy)`` -> (L, 5) mm.

    Places the robot and the Labbots where they are asked to be (the world re-places every body
    before its own contact checks) and returns, per Labbot and sensor, the free distance from
    the Labbot's rim to the first body, ``inf`` when none lies within ``labbot_sensor_range_mm``.
    """

    def __init__(self, scene: Scene) -> None:
        self.scene, self.p = scene, scene.p
        self.offsets = np.radians(LABBOT_SENSOR_DEG)
        labbots = cast(_Labbots, scene.o)  # built only for a room with Labbots: its options have their fields
        self.rim = labbots.labbot_radius_mm + _RIM_GAP_MM
        self.reach = labbots.labbot_sensor_range_mm - _RIM_GAP_MM

    def __call__(self, xy: np.ndarray, headings_deg: np.ndarray, robot_xy: np.ndarray) -> np.ndarray:
        scene = self.scene
        scene.place_robot(robot_xy, 0.0)  # a cylinder: its heading changes nothing a ray sees
        scene.place_labbots(xy, headings_deg)
        angles = (np.radians(np.asarray(headings_deg, dtype=float))[:, None] + self.offsets[None, :]).reshape(-1)
        centres = np.repeat(np.asarray(xy, dtype=float), len(self.offsets), axis=0)
        unit = np.column_stack((np.cos(angles), np.sin(angles)))
        z = np.full((len(angles), 1), LIDAR_HEIGHT_MM)
        start = np.hstack((centres + self.rim * unit, z)) / 1000.0
        end = np.hstack((centres + (self.rim + self.reach) * unit, z)) / 1000.0
        hits = self.p.rayTestBatch(start.tolist(), end.tolist(), numThreads=1,
                                   collisionFilterMask=OBSTACLE_GROUP | ROBOT_GROUP, physicsClientId=scene.client)
        free = np.array([_RIM_GAP_MM + hit[2] * self.reach if hit[0] >= 0 else np.inf for hit in hits])
        return free.reshape(len(xy), len(self.offsets))
