"""A served room's session as a run folder that ``show``, ``report`` and ``view`` read.

The session is one trial, ``<environment>/live/rosbridge/0``, of a scenario derived from the one
served: that environment alone, one arm ``live`` (no defence of ours: the room is the robot), one
condition ``rosbridge`` and the backend ``outside`` (the commands came from a client we did not
ask). Its ``scenario.json`` records that scenario, so every reader of run folders finds its cell.

Every command received is a step, written ahead before the room drives it (``status
executing``, the command as ``planned``) and again when the next command replaces it or it times
out: what the room did with it (``executed``: the distance and angle driven, a collision with what
was hit), the pose before and after, the room's clock. A command that could not be read is a step
too, never driven (``accepted`` false, the reason as its instruction's last words). A collision while
the robot stood is kept in that step's ``truth``, as the trial loop keeps one. The result is written
once, when an outcome is reached (collision, target, time limit) or the session ends (Ctrl-C,
SIGTERM): a session ended before any outcome is recorded ``timeout``, its detail saying it was ended,
at which time of the room's limit.

With ``bag`` (a storage, ``mcap`` or ``sqlite3``) the session is also a ROS 2 bag, ``bags/<trial>``
(:mod:`.session_bag`: what the room served and was told, on its clock), the run folder marked as
recording bags as ``ablate --bags`` marks one; :meth:`SessionRecord.close` puts it in place.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from ..runs.folder import RunFolder
from ..models.records import ErrorKind
from ..models import (
    ExecutedSignal,
    ExecutionResult,
    GroundTruth,
    Outcome,
    Pose,
    StepRecord,
    Straight,
    TrialResult,
    Turn,
)
from ..plugin.manager import Plugins
from ..plugin.refs import ComponentRef
from ..scenario import Condition, Scenario
from ..loop.defences import Defences
from ..runs.live_trial import LiveTrial
from ..runs.trial_files import bag_file, record_artefacts, trajectory_file
from .session_bag import Command, SessionBag

ARM, CONDITION = "live", "rosbridge"
#: The backend a session's scenario names: its commands came from a client, not from answers recorded here.
BACKEND = "outside"


def session_scenario(scenario: Scenario, label: str) -> Scenario:
    """The scenario a session records (module docstring)."""
    return scenario.model_copy(update={
        "name": f"{scenario.name}-served", "trials": 1, "environments": [scenario.environment(label)],
        "backend": ComponentRef(use=BACKEND), "arms": {ARM: Defences()}, "conditions": {CONDITION: Condition()}})


def is_session(scenario: Scenario) -> bool:
    """Whether a run folder's recorded scenario is a session's: its backend ``outside``, so it holds
    no answers to replay, and its bag (when it recorded one) is the record of what went on."""
    return scenario.backend.use == BACKEND


def held_signal(distance_mm: float, angle_deg: float) -> Straight | Turn | None:
    """The motion a held command made, as the contract's signal that names it best: a straight when
    it went somewhere (its direction the distance's sign), a turn when it turned on the spot."""
    if abs(distance_mm) >= 0.5:
        return Straight(command="straight", direction="forward" if distance_mm > 0 else "backward",
                        distance=abs(distance_mm))
    if abs(angle_deg) >= 0.05:
        return Turn(command="turn", direction="left" if angle_deg > 0 else "right", angle=abs(angle_deg))
    return None


class SessionRecord:
    """Writes a session's run folder as it goes (module docstring); used from one thread."""

    def __init__(self, scenario: Scenario, plugins: Plugins, folder: str | Path, seed: int, *,
                 bag: str | None = None, about: dict[str, Any] | None = None) -> None:
        self.scenario = scenario
        self.trial = LiveTrial(RunFolder(folder), scenario, label=scenario.environments[0].key, arm=ARM,
                               condition=CONDITION, seed=seed)
        self.folder, self.spec = self.trial.folder, self.trial.spec
        self.bag: SessionBag | None = None
        if bag is not None:  # before the store: a bag that cannot be opened leaves nothing open
            record_artefacts(self.folder.path, bags=bag)
            self.bag = SessionBag(bag_file(self.folder.path, self.spec.trial_id), bag)
            self.bag.started({"trial": self.spec.model_dump(mode="json"), "scenario": scenario.name, **(about or {})})
        try:
            self.store = self.trial.begin(plugins)
        except BaseException:
            if self.bag is not None:
                self.bag.close()
            raise
        self.steps = 0
        self.distance_mm = 0.0
        self.collisions: dict[str, int] = {"self": 0, "struck": 0, "standing": 0}
        self.self_hits: dict[str, int] = {}
        self.poses: list[Pose] = []
        self.result: TrialResult | None = None
        self._open: StepRecord | None = None
        self._moved = ExecutionResult()

    @property
    def path(self) -> Path:
        return self.folder.path

    def command(self, instruction: str, planned: list[Any], pose: Pose, time_s: float, truth: GroundTruth,
                accepted: bool = True) -> None:
        """A command arrived: close the open step and open this one, written ahead."""
        self.close_step(pose, truth, time_s)
        self.steps += 1
        record = StepRecord(trial_id=self.spec.trial_id, step=self.steps, instruction=instruction, planned=planned,
                            status="executing" if accepted and planned else "done", accepted=accepted,
                            pose_before=pose, truth=truth, sim_time_s=time_s)
        self.store.record_step(record)
        self._open, self._moved = record, ExecutionResult()

    def published(self, topic: str, message: dict[str, Any], time_s: float) -> None:
        """The room published ``message`` on ``topic`` at ``time_s``: kept in the bag, if any."""
        if self.bag is not None:
            self.bag.published(topic, message, time_s)

    def received(self, received: Command, time_s: float) -> None:
        """The room took a command at ``time_s``: kept in the bag, if any (the step is :meth:`command`'s)."""
        if self.bag is not None:
            self.bag.received(received, time_s)

    def driven(self, result: ExecutionResult) -> None:
        """What one tick of the room did under the open step's command (added up into the step)."""
        moved = self._moved
        collided = moved.collided or result.collided
        self._moved = ExecutionResult(
            distance_mm=moved.distance_mm + result.distance_mm, angle_deg=moved.angle_deg + result.angle_deg,
            stopped=moved.stopped or result.stopped, collided=collided,
            collision=moved.collision or result.collision, hit=moved.hit or result.hit,
            before_motion=moved.before_motion or result.before_motion,
            detail=moved.detail if not result.detail or result.detail in moved.detail
            else "; ".join(part for part in (moved.detail, result.detail) if part))
        self.distance_mm += abs(result.distance_mm)
        if result.collided:
            kind = result.collision or "self"
            self.collisions[kind] = self.collisions.get(kind, 0) + 1
            if kind == "struck" and result.before_motion:
                self.collisions["standing"] += 1
            if kind == "self":
                self.self_hits[result.hit or "unknown"] = self.self_hits.get(result.hit or "unknown", 0) + 1

    def close_step(self, pose: Pose, truth: GroundTruth, time_s: float) -> None:
        """Write the open step with what it did up to ``time_s`` (a no-op when none is open)."""
        record, moved = self._open, self._moved
        if record is None:
            return
        self._open = None
        if record.accepted:  # the signal names a straight or a turn: the words say the arc it drove
            held = f"{time_s - record.sim_time_s:.2f} s: {moved.distance_mm:.0f} mm, {moved.angle_deg:.1f} deg"
            moved = moved.model_copy(update={"detail": f"{held}; {moved.detail}" if moved.detail else held})
        executed = []
        signal = held_signal(moved.distance_mm, moved.angle_deg)
        if signal is None and moved.collided and not moved.before_motion and record.planned:
            signal = record.planned[0]  # it hit something before it had gone a millimetre
        if signal is not None:
            executed.append(ExecutedSignal(signal=signal, result=moved))
        if moved.collided and moved.before_motion:  # struck while standing: the truth keeps it, as the loop does
            truth = truth.model_copy(update={"collision": moved.collision, "hit": moved.hit,
                                             "collision_detail": moved.detail})
        self.store.record_step(record.model_copy(update={"executed": executed, "status": "done",
                                                         "pose_after": pose, "truth": truth}))

    def finish(self, outcome: Outcome, detail: str, pose: Pose, truth: GroundTruth, time_s: float,
               picture: bytes | None, wall_time_s: float = 0.0, error_kind: ErrorKind | None = None) -> None:
        """Close the open step and write the result and the path's picture (once)."""
        if self.result is not None:
            return
        self.close_step(pose, truth, time_s)
        self.result = TrialResult(
            spec=self.spec, outcome=outcome, steps=self.steps, distance_mm=self.distance_mm,
            collisions=self.collisions["self"] + self.collisions["struck"], collisions_self=self.collisions["self"],
            collisions_struck=self.collisions["struck"], collisions_struck_standing=self.collisions["standing"],
            self_collisions_hit=dict(self.self_hits), detail=detail, world=truth.world_kind or "",
            trajectory=[*self.poses, pose], wall_time_s=wall_time_s, error_kind=error_kind)
        self.trial.end(self.result)
        if self.bag is not None:
            self.bag.ended(self.result, time_s)
        if picture:
            target = trajectory_file(self.folder.path, self.spec.trial_id)
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(picture)

    def close(self) -> None:
        """Put the bag in place (if any) and close the store; once is enough, twice does no harm."""
        try:
            if self.bag is not None:
                self.bag.close()
        finally:
            self.trial.close()


def ended_detail(reason: str, time_s: float, limit_s: float | None) -> str:
    """The detail of a session ended before an outcome."""
    of = f" of the room's {limit_s:g} s limit" if limit_s is not None and math.isfinite(limit_s) else ""
    return f"the session was ended ({reason}) at {time_s:.1f} s{of}, before any outcome"
