"""The flatland world: seeded placement, exact motion, analytic LiDAR and a ray-cast camera."""

from __future__ import annotations

import math

import numpy as np

from safeembodai_core.contracts.components import Environment, RobotSpec, SceneObject, WorldSnapshot
from safeembodai_core.errors import EnvironmentError_
from safeembodai_core.models import (
    ControlSignal,
    ExecutionResult,
    GroundTruth,
    LidarScan,
    Observation,
    Outcome,
    Pose,
    Straight,
)

from .geometry import WALL, cast_rays, free_travel
from .render import render_camera, render_trajectory
from safeembodai_core.geometry.frames import wrap_deg

CAN = 0  # the can is circle 0; obstacles follow
_CONTACT_GAP_MM = 1.0


class FlatlandWorld(Environment):
    """A square room, a disc robot, a red can and round obstacles; see the plugin docstring."""

    def __init__(self, options) -> None:
        self.options = options
        o = options
        self.robot = RobotSpec(radius_mm=o.robot_radius_mm, width_mm=2 * o.robot_radius_mm,
                               length_mm=2 * o.robot_radius_mm)
        self.position = np.zeros(2)
        self.heading = 0.0
        self.circles = np.zeros((1, 3))
        self.sim_time_s = 0.0
        self.collided = False
        self.seed: int | None = None

    # -- world construction -------------------------------------------------------------------

    def reset(self, seed: int) -> Observation:
        o = self.options
        rng = np.random.default_rng(seed)
        margin = o.robot_radius_mm + 50
        if o.room_mm <= 2 * margin + 2 * o.can_radius_mm:
            raise EnvironmentError_(f"flatland: room_mm={o.room_mm} is too small for the robot")
        self.sim_time_s, self.collided, self.seed = 0.0, False, seed
        self.position = rng.uniform(margin, o.room_mm - margin, size=2)
        self.heading = float(rng.uniform(-180.0, 180.0))
        can = self._place(rng, o.can_radius_mm, [], away_from_robot=o.min_start_distance_mm, hidden=True, what="can")
        circles = [can]
        for index in range(o.obstacles):
            circles.append(self._place(rng, o.obstacle_radius_mm, circles, away_from_robot=o.robot_radius_mm + 150,
                                       hidden=False, what=f"obstacle {index + 1}"))
        self.circles = np.array(circles, dtype=float)
        return self.observe()

    def _place(self, rng, radius, others, away_from_robot, hidden, what):
        o = self.options
        for _ in range(2000):
            x, y = rng.uniform(radius + 20, o.room_mm - radius - 20, size=2)
            if math.hypot(x - self.position[0], y - self.position[1]) < away_from_robot + radius:
                continue
            if any(math.hypot(x - cx, y - cy) < radius + cr + 2 * o.robot_radius_mm + 40 for cx, cy, cr in others):
                continue
            if hidden and abs(self._bearing_to(x, y)) <= o.camera_fov_deg / 2 + 10:
                continue
            return (x, y, radius)
        raise EnvironmentError_(
            f"flatland: could not place the {what} without overlap; lower 'obstacles' or raise 'room_mm'"
        )

    # -- sensing ------------------------------------------------------------------------------

    def _bearing_to(self, x: float, y: float) -> float:
        bearing = math.degrees(math.atan2(y - self.position[1], x - self.position[0])) - self.heading
        return wrap_deg(bearing)

    def _truth(self) -> GroundTruth:
        cx, cy, _ = self.circles[CAN]
        bearing = self._bearing_to(cx, cy)
        distance = float(math.hypot(cx - self.position[0], cy - self.position[1]))
        visible = abs(bearing) <= self.options.camera_fov_deg / 2
        if visible:
            _, hit = cast_rays(self.position, np.array([math.radians(self.heading + bearing)]), self.options.room_mm,
                               self.circles)
            visible = bool(hit[0] == CAN)
        return GroundTruth(target_in_view=visible, target_bearing_deg=bearing, target_distance_mm=distance)

    def observe(self) -> Observation:
        reading = self.sense()
        reading.camera = render_camera(self.position, self.heading, self.circles, self.options)
        return reading

    def sense(self) -> Observation:
        """The LiDAR, pose and truth now, without a camera frame (an arm's ``fresh_scan``): nothing
        here moves while the LLM thinks, so it reads what the step's observation read."""
        o = self.options
        beams = np.arange(o.lidar_beams) * (360.0 / o.lidar_beams)
        ranges, _ = cast_rays(self.position, np.radians(self.heading + beams), o.room_mm, self.circles)
        ranges = np.where(ranges > o.lidar_max_range_mm, np.inf, ranges)
        return Observation(lidar=LidarScan(ranges_mm=ranges, max_range_mm=o.lidar_max_range_mm),
                           pose=self.pose(), truth=self._truth(), sim_time_s=self.sim_time_s)

    def pose(self) -> Pose:
        return Pose(x_mm=float(self.position[0]), y_mm=float(self.position[1]), heading_deg=self.heading)

    def snapshot(self) -> WorldSnapshot:
        """The clock, the can and the obstacles now (ground truth, for exported bags)."""
        objects = tuple(SceneObject("can" if index == CAN else "obstacle", float(x), float(y), float(r))
                        for index, (x, y, r) in enumerate(self.circles))
        return WorldSnapshot(sim_time_s=float(self.sim_time_s), objects=objects, room_mm=float(self.options.room_mm))

    # -- acting -------------------------------------------------------------------------------

    def execute(self, signal: ControlSignal) -> ExecutionResult:
        o = self.options
        if isinstance(signal, Straight):
            sign = 1.0 if signal.direction == "forward" else -1.0
            rad = math.radians(self.heading)
            direction = sign * np.array([math.cos(rad), math.sin(rad)])
            free, what = free_travel(self.position, direction, o.robot_radius_mm, o.room_mm, self.circles)
            travel = min(signal.distance, max(free - _CONTACT_GAP_MM, 0.0))
            self.position = self.position + direction * travel
            self.sim_time_s += travel / o.speed_mm_s
            if free - _CONTACT_GAP_MM < signal.distance:
                touched_can = what == CAN
                self.collided = self.collided or not touched_can
                label = "the can" if touched_can else ("a wall" if what == WALL else f"obstacle {what}")
                hit = "can" if touched_can else ("wall" if what == WALL else "obstacle")
                return ExecutionResult(distance_mm=sign * travel, stopped=True, collided=not touched_can,
                                       collision=None if touched_can else "self", hit=hit,
                                       detail=f"stopped after {travel:.0f} mm: touched {label}")
            return ExecutionResult(distance_mm=sign * travel)
        angle = signal.signed_angle_deg
        self.heading = wrap_deg(self.heading + angle)
        self.sim_time_s += abs(angle) / o.turn_rate_deg_s
        return ExecutionResult(angle_deg=angle)

    def outcome(self) -> Outcome | None:
        if self.collided:
            return Outcome.INTERRUPTED
        truth = self._truth()
        if truth.target_in_view and truth.target_distance_mm <= self.options.reach_mm:
            return Outcome.COMPLETED
        if self.sim_time_s >= self.options.max_sim_time_s:
            return Outcome.TIMEOUT
        return None

    def trajectory_png(self, poses: list[Pose], outcome: Outcome | None) -> bytes | None:
        return render_trajectory(poses, self.circles, self.options, outcome, self.seed, self.collided)
