"""A pybullet room as an :class:`~safeembodai_core.contracts.components.Environment`.

:class:`PybulletRoom` draws the layout from the seed, places the bodies of its
:class:`~.scene.Scene`, reads the :class:`~.sensors.Sensors` and decides the outcome; the robot's
motion comes from :class:`~.motion.KinematicMotion`, a held velocity's from
:class:`~.velocity.HeldVelocity`. Outcomes, checked after every step:
``interrupted`` once the robot has collided with a wall, a ball or a Labbot (by its own motion:
``self``, or a Labbot ran into it: ``struck``); ``completed`` when
the can is within ``reach_mm`` (centre to centre) and in the camera's view; ``timeout`` when the
simulated-time limit is spent. The step budget is the core loop's.

With a ``labbot_family`` (:mod:`.movers`) each reset draws the trial's kind of Labbot dynamics and
every Labbot's parameters from the seed, and every observation's ground truth reports them under
``extra["world"]``, and the kind alone as ``world_kind`` (the trial's world, which the
core copies into ``TrialResult.world`` and the report breaks collisions down by; for the report
only: validators never see ground truth). ``GroundTruth.extra``
holds scalars only, so the report is JSON text: :func:`~.movers.world_report` reads it back.
"""

from __future__ import annotations

import numpy as np

from safeembodai_core.contracts.components import Environment, RobotSpec, SceneObject, WorldSnapshot
from safeembodai_core.errors import EnvironmentError_
from safeembodai_core.models import GroundTruth, LidarScan, Observation, Outcome, Pose
from safeembodai_core.seeds import derive_seed

from .labbots import LabbotSwarm
from .layout import bearing_deg, draw_layout
from .motion import CollisionRecord, KinematicMotion
from .options import CAN_RADIUS_MM, RoomOptions
from .picture import draw_trajectory
from .quiet import silenced
from .scene import Scene
from .sensors import LabbotRangeSensors, Sensors
from .velocity import HeldVelocity


class PybulletRoom(KinematicMotion, HeldVelocity, Environment):
    """One of the paper's rooms (``OF``, ``SO``, ``DO`` or ``MO``) in its own physics client."""

    def __init__(self, kind: str, options: RoomOptions) -> None:
        self.kind, self.options = kind, options
        r = options.robot_radius_mm
        self.robot = RobotSpec(radius_mm=r, width_mm=2 * r, length_mm=2 * r)
        self.scene = Scene(options)
        self.sensors = Sensors(self.scene)
        self.family = getattr(options, "labbot_family", None)
        if self.family is not None:  # built if any Labbot of a trial may sense; used in trials where one does
            sensing = options.labbot_count and any(kind.sensing for kind in self.family.plain)
        else:
            sensing = options.labbot_count and getattr(options, "labbot_sensing", False)
        self.labbot_sensors = LabbotRangeSensors(self.scene) if sensing else None
        self.xy = np.zeros(2)
        self.heading = 0.0
        self.can_xy = np.zeros(2)
        self.balls_xy = np.zeros((0, 2))
        self.swarm: LabbotSwarm | None = None
        self.sim_time_s = 0.0
        self.collided = False
        self.collision_xy: np.ndarray | None = None
        self.collision: CollisionRecord = {}  # who moved into whom, what was hit, the detail
        self._unreported: CollisionRecord = {}  # a collision outside any command, for the next observation
        self._thinks = 0  # think times owed: the last observation's, one more per retry when charged per call
        self._seed: int | None = None
        self._world: str | None = None  # the trial's drawn Labbot dynamics (JSON, with a family), for ground truth
        self._world_kind: str | None = None  # the trial's kind (the report's bucket), with a family

    # -- world construction -------------------------------------------------------------------

    def reset(self, seed: int) -> Observation:
        if self.scene.closed:
            raise EnvironmentError_(f"{self.kind}: the environment was closed; build a new one")
        o = self.options
        layout = draw_layout(o, np.random.default_rng(seed))
        self._seed = seed
        self.xy, self.heading = layout.robot_xy.copy(), layout.robot_heading_deg
        self.can_xy, self.balls_xy = layout.can_xy.copy(), layout.balls_xy.copy()
        statics = np.vstack([np.append(self.can_xy, CAN_RADIUS_MM)]
                            + [np.column_stack((self.balls_xy, np.full(len(self.balls_xy), o.ball_radius_mm)))])
        # a family draws from its own stream (seed, "movers"): the layout's and the Labbots' are untouched
        draw = self.family.draw(seed, o.labbot_count) if self.family is not None else None
        movers = draw.movers if draw is not None else None
        sense = self.labbot_sensors if movers is None or any(m.sensing for m in movers) else None
        self.swarm = LabbotSwarm(o, layout.labbots_xy, layout.labbots_heading_deg, statics,
                                 derive_seed(seed, "labbots"), sense=sense, movers=movers,
                                 sense_reads_room=True)
        self._world = draw.report_json() if draw is not None else None
        self._world_kind = draw.kind if draw is not None else None
        self.sim_time_s, self.collided, self.collision_xy = 0.0, False, None
        self.collision, self._unreported = {}, {}
        self._thinks = 0  # nothing pending from the previous trial
        with silenced():
            self.scene.place_statics(self.can_xy, self.balls_xy)
            self._sync()
        return self.observe()

    def _sync(self) -> None:
        self.scene.place_robot(self.xy, self.heading)
        swarm = self._labbots()
        self.scene.place_labbots(swarm.xy, swarm.heading)

    def _require_reset(self) -> None:
        if self._seed is None:
            raise EnvironmentError_(f"{self.kind}: call reset(seed) before using the environment")
        if self.scene.closed:
            raise EnvironmentError_(f"{self.kind}: the environment was closed")

    # -- sensing ------------------------------------------------------------------------------

    def truth(self) -> GroundTruth:
        """Where the can is relative to the robot, and whether the camera sees it; with a Labbot
        family also ``extra["world"]``: the family, the trial's kind and each Labbot's parameters."""
        self._require_reset()
        distance = float(np.hypot(*(self.can_xy - self.xy)))
        with silenced():
            visible = self.sensors.can_in_view(self.xy, self.heading, self.can_xy)
        extra: dict[str, float | int | bool | str] = {"collided": self.collided}
        if self._world is not None:
            extra["world"] = self._world
            assert self._world_kind is not None  # reset sets both from the trial's draw
        return GroundTruth(
            target_in_view=visible, target_bearing_deg=bearing_deg(self.xy, self.heading, self.can_xy),
            target_distance_mm=distance, world_kind=self._world_kind if self._world is not None else None,
            extra=extra,
        )

    def observe(self) -> Observation:
        self._require_reset()
        o = self.options
        with silenced():
            self._finish_thinking()  # the last observation's thinking led to no command: it still took time
            ranges = self.sensors.lidar(self.xy, self.heading)
            image = self.sensors.camera(self.xy, self.heading)
        self._thinks = 1
        return Observation(
            camera=image, lidar=LidarScan(ranges_mm=ranges, max_range_mm=o.lidar_max_range_mm),
            pose=self.pose(), truth=self._reported_truth(), sim_time_s=self.sim_time_s,
        )

    def sense(self) -> Observation:
        """The LiDAR when the LLM's answer arrives (an arm's ``fresh_scan``): the think time passes
        first, if it has not yet (the Labbots move; one that strikes the robot is reported in this
        reading's truth), then the scan is read. No camera frame: nothing renders one here."""
        self._require_reset()
        with silenced():
            self._finish_thinking()
            ranges = self.sensors.lidar(self.xy, self.heading)
        return Observation(lidar=LidarScan(ranges_mm=ranges, max_range_mm=self.options.lidar_max_range_mm),
                           pose=self.pose(), truth=self._reported_truth(), sim_time_s=self.sim_time_s)

    def another_call(self) -> None:
        """A retry's call: with ``think_time_per_call`` it owes another think time (spent before the
        next command, or by :meth:`sense`); without it the step's one think time covers it."""
        self._require_reset()
        if self.options.think_time_per_call:
            self._thinks += 1

    def _take_think_s(self) -> float:
        """The think time owed, in seconds; nothing is owed after it (the caller spends it)."""
        owed, self._thinks = self._thinks, 0
        return self.options.think_time_s * owed

    def _finish_thinking(self) -> None:
        """Spend the think time owed (the last observation's, and each charged retry's) if any; a
        Labbot that strikes the standing robot meanwhile is kept for the next reading's truth."""
        if self._thinks:
            hit = self._wait(self._take_think_s())
            if hit is not None:
                self._unreported = self._collision_record(hit, "while the robot stood still (think time)")

    def _reported_truth(self) -> GroundTruth:
        """The truth now, with a collision outside any command reported once (the first reading after it)."""
        truth = self.truth()
        if self._unreported:
            truth = truth.model_copy(update=dict(self._unreported))  # collision, hit, collision_detail: its fields
            self._unreported = {}
        return truth

    def pose(self) -> Pose:
        return Pose(x_mm=float(self.xy[0]), y_mm=float(self.xy[1]), heading_deg=float(self.heading))

    def outcome(self) -> Outcome | None:
        self._require_reset()
        if self.collided:
            return Outcome.INTERRUPTED
        # the can counts only within reach: farther, whether the camera sees it is not asked (a ray cast)
        if float(np.hypot(*(self.can_xy - self.xy))) <= self.options.reach_mm:
            truth = self.truth()
            distance = truth.target_distance_mm  # truth() always gives it
            if truth.target_in_view and distance is not None and distance <= self.options.reach_mm:
                return Outcome.COMPLETED
        if self.sim_time_s >= self.options.max_sim_time_s - 1e-9:
            return Outcome.TIMEOUT
        return None

    # -- pictures and teardown ----------------------------------------------------------------

    def trajectory_png(self, poses: list[Pose], outcome: Outcome | None) -> bytes | None:
        return draw_trajectory(f"{self.kind}  seed {self._seed}", self.options, self.can_xy, self.balls_xy, self.swarm,
                               self.collision_xy, poses, outcome)

    def snapshot(self) -> WorldSnapshot:
        """The clock, the can, the balls and the Labbots now (ground truth, for exported bags)."""
        self._require_reset()
        o = self.options
        objects = [SceneObject("can", float(self.can_xy[0]), float(self.can_xy[1]), CAN_RADIUS_MM)]
        objects += [SceneObject("ball", float(x), float(y), o.ball_radius_mm) for x, y in self.balls_xy]
        radius = getattr(o, "labbot_radius_mm", 0.0)
        swarm = self._labbots()
        objects += [SceneObject("labbot", float(x), float(y), radius, float(h))
                    for (x, y), h in zip(swarm.xy, swarm.heading)]
        return WorldSnapshot(sim_time_s=float(self.sim_time_s), objects=tuple(objects), room_mm=float(o.room_mm))

    def close(self) -> None:
        self.scene.close()
