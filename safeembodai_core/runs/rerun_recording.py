"""A trial as a Rerun recording (``.rrd``): the room in 3D on the trial's simulated timeline.

Written with ``rerun-sdk`` (the ``rerun`` extra) from the trial's step records and what
:class:`~safeembodai_core.loop.capture.TrialCapture` saw when the trial was replayed -- the same
sources as an exported bag (:mod:`safeembodai_core.ros.bag_export`). World frame in metres, z up,
the room's corner at the origin. Entities (:data:`ENTITIES`):

* ``world/room`` -- the room's walls (static);
* ``world/objects/<kind>`` -- the can, balls, Labbots and obstacles (the simulator's ground truth)
  at each observation and after each command;
* ``world/robot`` -- the robot's pose over time (a transform), its body under ``world/robot/body``;
* ``world/trajectory`` -- the path driven so far; ``world/collisions`` -- where it collided;
* ``world/scan`` -- each step's scan as the rules read it (after any sensor attack), as points in
  the world frame, from the pose at which it was taken;
* ``world/plans/attempt_<j>`` -- each attempt's plan as the path it would drive from the step's
  pose (accepted green, refused red; an answer that did not parse has none), cleared at the next
  step; ``world/plans/attempt_<j>/blocked_by`` -- for a refused straight, the nearest return of
  the step's scan in its corridor (the body's width) from its start on (computed here, for the eye:
  the rule's own reasoning is in the log);
* ``images/<name>`` -- the camera and LiDAR pictures the LLM was shown;
* ``log`` -- the instruction, attacks, the LLM's answers, refusals and acceptances, executed
  commands, collisions and the outcome, as text (control characters shown as escapes).

Timelines: ``sim_time`` (simulated seconds) and ``step``.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from ..contracts.components import WorldSnapshot
from ..errors import SafeEmbodAIError
from ..loop.capture import Executed, Observed, Seen, TrialCapture
from ..geometry.plans import nearest_ahead, plan_path, scan_points
from ..models import Pose, StepRecord, Straight, TrialResult, TrialSpec
from ..contracts.robot import RobotSpec
from ..trust.text import terminal_text

#: Every entity path a recording may hold (``<...>``: one per kind, attempt or image).
ENTITIES = ("world/room", "world/objects/<kind>", "world/robot", "world/robot/body", "world/trajectory",
            "world/collisions", "world/scan", "world/plans/attempt_<j>", "world/plans/attempt_<j>/blocked_by",
            "images/<name>", "log")
GREEN, RED = (40, 190, 70), (220, 40, 40)
_COLOURS = {"can": (220, 25, 25), "ball": (235, 235, 235), "labbot": (255, 140, 0), "obstacle": (128, 128, 128),
            "robot": (25, 100, 230), "scan": (90, 160, 255), "trajectory": (25, 100, 230)}
_HEIGHT_M = {"robot": 0.25, "can": 0.12, "ball": 0.22, "labbot": 0.2, "obstacle": 0.3}
WALL_HEIGHT_M = 0.3


def import_rerun() -> Any:
    try:
        import rerun
    except ImportError:
        raise SafeEmbodAIError('a Rerun recording needs the rerun extra: pip install -e ".[rerun]"') from None
    return rerun


def _text(value: Any) -> str:
    return terminal_text(str(value), keep_layout=True)


def _m(mm: float) -> float:
    return float(mm) / 1000.0


class _Writer:
    """One recording: what it logs, on the clock of the capture's events."""

    def __init__(self, rr: Any, stream: Any, robot: RobotSpec) -> None:
        self.rr, self.stream, self.robot = rr, stream, robot
        self.path: list[list[float]] = []
        self.collisions: list[list[float]] = []
        self.kinds: set[str] = set()

    def at(self, seconds: float, step: int) -> None:
        self.stream.set_time("sim_time", duration=max(0.0, float(seconds)))
        self.stream.set_time("step", sequence=step)

    def log(self, level: str, text: str) -> None:
        self.stream.log("log", self.rr.TextLog(_text(text), level=level))

    def static(self, world: WorldSnapshot | None) -> None:
        rr = self.rr
        robot = self.robot
        height = _HEIGHT_M["robot"]
        self.stream.log("world/robot/body", rr.Cylinders3D(lengths=[height], radii=[_m(robot.radius_mm)],
                                                           centers=[[0.0, 0.0, height / 2]],
                                                           colors=[_COLOURS["robot"]]), static=True)
        if world is not None and world.room_mm:
            side = _m(world.room_mm)
            h = WALL_HEIGHT_M / 2
            centres = [[side / 2, 0, h], [side, side / 2, h], [side / 2, side, h], [0, side / 2, h]]
            sizes = [[side / 2, 0.01, h], [0.01, side / 2, h], [side / 2, 0.01, h], [0.01, side / 2, h]]
            self.stream.log("world/room", rr.Boxes3D(centers=centres, half_sizes=sizes, colors=[(110, 110, 110)]),
                            static=True)

    def world(self, world: WorldSnapshot | None, pose: Pose | None) -> None:
        rr = self.rr
        if world is not None:
            by_kind: dict[str, list[Any]] = {}
            for item in world.objects:
                by_kind.setdefault(item.kind, []).append(item)
            for kind in sorted(set(by_kind) | self.kinds):
                items = by_kind.get(kind, [])
                height = _HEIGHT_M.get(kind, 0.2)
                self.stream.log(f"world/objects/{kind}", rr.Cylinders3D(
                    lengths=[height] * len(items), radii=[_m(i.radius_mm) for i in items],
                    centers=[[_m(i.x_mm), _m(i.y_mm), height / 2] for i in items],
                    colors=[_COLOURS.get(kind, (150, 80, 200))] * len(items)))
            self.kinds |= set(by_kind)
        if pose is not None:
            self.stream.log("world/robot", rr.Transform3D(
                translation=[_m(pose.x_mm), _m(pose.y_mm), 0.0],
                rotation=rr.RotationAxisAngle(axis=[0.0, 0.0, 1.0], radians=math.radians(pose.heading_deg))))
            point = [_m(pose.x_mm), _m(pose.y_mm), 0.01]
            if not self.path or self.path[-1] != point:
                self.path.append(point)
                self.stream.log("world/trajectory", rr.LineStrips3D([self.path], colors=[_COLOURS["trajectory"]]))

    def seen(self, event: Seen, pose: Pose | None, record: StepRecord | None) -> None:
        rr = self.rr
        self.stream.log("world/plans", rr.Clear(recursive=True))
        points = scan_points(event.scan, pose) if event.scan is not None and pose is not None else np.zeros((0, 2))
        if event.scan is not None and pose is not None:
            self.stream.log("world/scan", rr.Points3D([[_m(x), _m(y), 0.05] for x, y in points],
                                                      radii=[0.015], colors=[_COLOURS["scan"]]))
        for name, image in sorted(event.images.items()):
            self.stream.log(f"images/{name}", rr.EncodedImage(contents=image.data, media_type=image.media_type))
        if record is None:
            return
        for attack in record.attacks:
            self.log("WARN", f"step {record.step}: {attack.kind} injected through the {attack.channel}: "
                             f"{attack.payload}")
        self.log("INFO", f"step {record.step}: instruction: {record.instruction}")
        for attempt in record.attempts:
            self._attempt(record.step, attempt, pose, points)

    def _attempt(self, step: int, attempt: Any, pose: Pose | None, points: np.ndarray) -> None:
        rr = self.rr
        where = f"step {step}, attempt {attempt.index + 1}"
        self.log("DEBUG", f"{where}: the LLM answered: {attempt.raw_text}")
        if attempt.accepted:
            self.log("INFO", f"{where}: accepted")
        else:
            self.log("WARN", f"{where}: refused: " + "; ".join(attempt.failures()))
        if attempt.response is None or pose is None:
            return
        path, segments = plan_path(pose, list(attempt.response.control))
        entity = f"world/plans/attempt_{attempt.index + 1}"
        self.stream.log(entity, rr.LineStrips3D([[[_m(x), _m(y), 0.02] for x, y in path]],
                                                colors=[GREEN if attempt.accepted else RED], radii=[0.01]))
        blocked = []
        for verdict in attempt.verdicts:
            index = verdict.signal_index
            if verdict.valid or index is None or not 0 <= index < len(segments):
                continue
            if not isinstance(attempt.response.control[index], Straight):
                continue
            start, end = segments[index]
            found = nearest_ahead(points, start, end, self.robot.radius_mm)
            if found is not None:
                blocked.append([_m(found[0]), _m(found[1]), 0.05])
        if blocked:
            self.stream.log(f"{entity}/blocked_by", rr.Points3D(blocked, radii=[0.05], colors=[RED]))

    def executed(self, event: Executed) -> None:
        self.log("INFO", f"step {event.step}: executing {event.signal.describe()}")

    def collided(self, event: Executed, pose: Pose) -> None:
        self.collisions.append([_m(pose.x_mm), _m(pose.y_mm), 0.1])
        self.stream.log("world/collisions", self.rr.Points3D(self.collisions, radii=[0.08], colors=[RED]))
        self.log("ERROR", f"step {event.step}: {event.result.collision or 'unattributed'} collision: "
                          f"{event.result.detail}")


def write_recording(path: str | Path, spec: TrialSpec, records: list[StepRecord], result: TrialResult | None,
                    capture: TrialCapture, robot: RobotSpec) -> Path:
    """Write the trial as a ``.rrd`` at ``path`` (written aside, then renamed into place: a failure
    leaves nothing there); return the path. Needs the ``rerun`` extra."""
    rr = import_rerun()
    path = Path(path)
    if path.exists():
        raise SafeEmbodAIError(f"{path} exists: a recording is never written over")
    path.parent.mkdir(parents=True, exist_ok=True)
    partial = path.with_name(f".{path.name}.partial")
    stream = rr.RecordingStream("safeembodai", recording_id=spec.trial_id)
    try:
        stream.save(partial)
        stream.send_recording_name(_text(spec.trial_id))
        writer = _Writer(rr, stream, robot)
        by_step = {record.step: record for record in records}
        pose: Pose | None = None
        now, step = 0.0, 0
        writer.at(0.0, 0)
        first = next((e.world for e in capture.events if isinstance(e, Observed)), None)
        writer.static(first)
        writer.log("INFO", f"{spec.trial_id} (seed {spec.seed})")
        for event in capture.events:
            if isinstance(event, Observed):
                now, pose = event.sim_time_s, event.pose or pose
                writer.at(now, step)
                writer.world(event.world, pose)
            elif isinstance(event, Seen):
                step = event.step
                writer.at(now, step)
                writer.seen(event, pose, by_step.get(event.step))
            else:
                if event.before is not None:
                    now = event.before.sim_time_s
                writer.at(now, step)
                writer.executed(event)
                now = event.after.sim_time_s if event.after is not None else now
                pose = event.pose_after or pose
                writer.at(now, step)
                writer.world(event.after, pose)
                if event.result.collided and pose is not None:
                    writer.collided(event, pose)
        if result is not None:
            writer.at(now, step)
            writer.log("INFO", f"{spec.trial_id}: {result.outcome.value}"
                               + (f" ({result.detail})" if result.detail else ""))
        stream.flush()
    except BaseException:
        stream.disconnect()
        partial.unlink(missing_ok=True)
        raise
    stream.disconnect()
    partial.replace(path)
    return path


def recording_bytes(spec: TrialSpec, records: list[StepRecord], result: TrialResult | None, capture: TrialCapture,
                    robot: RobotSpec) -> bytes:
    """The trial's ``.rrd`` as bytes (:func:`write_recording` in a scratch folder of this machine):
    what a run writes as each trial ends, in the run folder or, from a Ray node, through the relay."""
    import tempfile

    with tempfile.TemporaryDirectory(prefix="safeembodai-rrd-") as scratch:
        path = write_recording(Path(scratch) / "trial.rrd", spec, records, result, capture, robot)
        return path.read_bytes()
