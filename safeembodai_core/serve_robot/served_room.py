"""One room on the wall clock: held velocity commands in, the room's sensors out.

:class:`ServedRoom` owns the room (an :class:`~safeembodai_core.contracts.components.Environment` that
implements ``drive``) and runs its clock in the calling thread. The room's time follows the wall
clock (times ``speed``): the loop drives the world up to now under the command being held, then
publishes what is due -- ``/scan`` at ``scan_hz``, ``/odom`` at ``odom_hz``, the camera at
``camera_hz`` -- and sleeps until the next thing due or the next command, whichever comes first.

A command (:meth:`ServedRoom.command`, called from the server's thread) is queued with the wall time
it arrived; the loop first drives the world up to that moment under the command it held, then holds
the new one, as a differential drive's controller does: until the next command, or for
``cmd_vel_timeout_s`` (ros2_control's ``diff_drive_controller``: 0.5 s), then a stop. A command that
cannot be read is a stop, recorded with the reason; it never reaches the room.

The outcome is the room's own (a collision, the target reached, its time limit): the moment it
comes, ``/safeembodai/events`` says so, the result is written and the robot drives no more (its
sensors keep being served). Stopping the loop (:meth:`ServedRoom.stop`, SIGINT, SIGTERM) writes the
record of a session that reached no outcome.
"""

from __future__ import annotations

import math
import threading
import time
from collections import deque
from dataclasses import dataclass
from typing import Any, Callable

import structlog

from ..contracts.components import Environment
from ..models import ExecutionResult, GroundTruth, Outcome
from ..models.records import ErrorKind
from ..ros.twist import Twist, arc_signals
from . import messages
from .session_record import SessionRecord, ended_detail

log = structlog.get_logger(__name__)

#: The longest the loop sleeps (seconds): a stop request is seen this soon.
MAX_SLEEP_S = 0.05
#: The fastest command passed to the room as it is (m/s, rad/s); a faster one is scaled to these first.
MAX_LINEAR_M_S = 100.0
MAX_ANGULAR_RAD_S = 100.0
#: Commands queued before the loop takes them; beyond this the oldest are dropped (and recorded so).
MAX_QUEUED = 256


@dataclass(frozen=True)
class Rates:
    """How often each stream is published (Hz) and how long a command is held (seconds)."""

    scan_hz: float = 10.0
    odom_hz: float = 20.0
    camera_hz: float = 5.0
    cmd_vel_timeout_s: float = 0.5

    def __post_init__(self) -> None:
        for name in ("scan_hz", "odom_hz", "camera_hz", "cmd_vel_timeout_s"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0 < value <= 1000):
                raise ValueError(f"{name} must be a number in (0, 1000], got {value!r}")


@dataclass(frozen=True)
class Received:
    """A command as it arrived: the twist (None when unreadable, with ``error``), its topic and type,
    the client, and the wall time."""

    twist: Twist | None
    topic: str
    type: str
    client: str
    wall_s: float
    error: str = ""


class ServedRoom:
    """The room's real-time loop (module docstring)."""

    def __init__(self, environment: Environment, record: SessionRecord, publish: Callable[[str, dict], None], *,
                 seed: int, speed: float = 1.0, rates: Rates | None = None, time_limit_s: float | None = None,
                 read_twist: Callable[[Any], Twist] = Twist.from_ros) -> None:
        if not (math.isfinite(speed) and 0.01 <= speed <= 100.0):
            raise ValueError(f"speed must be between 0.01 and 100, got {speed!r}")
        self.environment, self.record, self._wire = environment, record, publish
        self.speed, self.rates, self.time_limit_s = speed, rates or Rates(), time_limit_s
        self.read_twist = read_twist
        self.seed = seed
        self._queue: deque[Received] = deque()
        self._lock = threading.Lock()
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._stop_reason = ""
        self.sim_s = 0.0
        self.held = Twist(0.0, 0.0)
        self.held_until_s = 0.0  # the room's time the held command runs out
        self.outcome: Outcome | None = None
        self.dropped = 0
        self._start_wall: float | None = None
        self._due = {"scan": 0.0, "odom": 0.0, "camera": 0.0}

    # -- from the server's thread -----------------------------------------------------------------

    def command(self, message: Any, topic: str, type_: str, client: str) -> None:
        """A velocity command arrived (any thread): read it, queue it with its arrival time. An
        unreadable one is queued as a stop with the reason, and ``ValueError`` tells the caller."""
        wall = time.monotonic()
        try:
            twist, error = self.read_twist(message), ""
        except (TypeError, ValueError) as failure:
            twist, error = None, str(failure)
        with self._lock:
            if len(self._queue) >= MAX_QUEUED:
                self._queue.popleft()
                self.dropped += 1
            self._queue.append(Received(twist, topic, type_, client, wall, error))
        self._wake.set()
        if error:
            raise ValueError(f"{topic}: {error}: the robot stops")

    def stop(self, reason: str = "stopped") -> None:
        """End the loop (any thread, a signal handler too)."""
        self._stop_reason = self._stop_reason or reason
        self._stop.set()
        self._wake.set()

    # -- the loop ---------------------------------------------------------------------------------

    def run(self) -> None:
        """Serve until :meth:`stop`; the record is written whatever ends it."""
        self._start_wall = time.monotonic()
        try:
            while not self._stop.is_set():
                self._advance_to(self._room_time(time.monotonic()))
                self._publish_due()
                self._wake.wait(self._sleep_s())
                self._wake.clear()
        except Exception as error:  # a failure of the room or the record: on record as such, then raised
            log.error("serve_robot.failed", error=repr(error)[:300])
            self._finish(Outcome.ERROR, f"the served room failed: {error}"[:500], "session_failed", error_kind="crash")
            raise
        finally:
            if self.outcome is None:
                reason = self._stop_reason or "stopped"
                self._finish(Outcome.TIMEOUT, ended_detail(reason, self.sim_s, self.time_limit_s), "session_ended")

    def _room_time(self, wall: float) -> float:
        assert self._start_wall is not None
        return (wall - self._start_wall) * self.speed

    def _sleep_s(self) -> float:
        """Until the next publication or the held command's end, at most :data:`MAX_SLEEP_S`."""
        due = min(self._due.values())
        if self.held != Twist(0.0, 0.0):
            due = min(due, self.held_until_s)
        return max(0.0, min((due - self.sim_s) / self.speed, MAX_SLEEP_S))

    def _advance_to(self, target_s: float) -> None:
        """Drive the world to ``target_s``, taking each queued command at the time it arrived."""
        while True:
            with self._lock:
                received = self._queue.popleft() if self._queue else None
            if received is None:
                break
            self._drive_until(min(self._room_time(received.wall_s), target_s))
            self._take(received)
        self._drive_until(target_s)

    def _drive_until(self, target_s: float) -> None:
        while self.sim_s < target_s - 1e-9:
            until = target_s
            moving = self.held != Twist(0.0, 0.0)
            if moving and self.held_until_s > self.sim_s:
                until = min(until, self.held_until_s)
            elif moving:  # the held command ran out: a stop, as the base's controller does
                self.held = Twist(0.0, 0.0)
            self._drive(self.held if self.held_until_s > self.sim_s else Twist(0.0, 0.0), until - self.sim_s)

    def _drive(self, twist: Twist, seconds: float) -> None:
        if self.outcome is not None:
            twist = Twist(0.0, 0.0)  # the trial is over: the robot drives no more
        # no base drives faster than this: an absurd command is scaled down first (its curvature kept), so the
        # room's units stay finite; the room then caps it at its own limits and says so
        factor = max(abs(twist.linear_x) / MAX_LINEAR_M_S, abs(twist.angular_z) / MAX_ANGULAR_RAD_S, 1.0)
        result = self.environment.drive(twist.linear_x / factor * 1000.0, math.degrees(twist.angular_z / factor),
                                        seconds)
        if result is None:  # the plan refused such a room before the session started
            raise RuntimeError("the environment cannot be driven by velocity")
        self.sim_s += seconds
        if self.outcome is None:
            self.record.driven(result)
            if result.collided:
                self._decide(result)

    def _take(self, received: Received) -> None:
        self.record.received(received, self.sim_s)
        pose, truth = self._pose(), self._truth()
        if received.twist is None:
            self.held, self.held_until_s = Twist(0.0, 0.0), self.sim_s
            self.record.command(f"{received.topic} ({received.type}) from {received.client}: not read, the robot "
                                f"stops: {received.error}", [], pose, self.sim_s, truth, accepted=False)
            return
        twist = received.twist
        timeout = self.rates.cmd_vel_timeout_s
        words = (f"{received.topic} ({received.type}) from {received.client}: linear.x {twist.linear_x:.4g} m/s, "
                 f"angular.z {twist.angular_z:.4g} rad/s, held up to {timeout:g} s")
        if self.outcome is not None:
            words += f"; not driven: the trial had ended ({self.outcome.value})"
        try:
            planned = arc_signals(twist, timeout, step_mm=1000.0, step_deg=90.0) if twist != Twist(0, 0) else []
        except ValueError:  # an arc too long to cut: recorded by its words alone
            planned = []
        self.record.command(words, planned, pose, self.sim_s, truth)
        self.held, self.held_until_s = twist, self.sim_s + timeout

    def publish(self, topic: str, message: dict) -> None:
        """Out on the wire, and into the session's record (its bag) at the room's time."""
        self._wire(topic, message)
        self.record.published(topic, message, self.sim_s)

    # -- readings ---------------------------------------------------------------------------------

    def _pose(self) -> Any:
        pose = self.environment.pose()
        assert pose is not None, "a served room says where its robot is"
        return pose

    def _truth(self) -> GroundTruth:
        truth = getattr(self.environment, "truth", None)  # the room's own, for the record only
        return truth() if callable(truth) else GroundTruth()

    def _publish_due(self) -> None:
        now = self.sim_s
        if now >= self._due["scan"]:
            self._schedule("scan", self.rates.scan_hz, now)
            reading = self.environment.sense()
            if reading is not None and reading.lidar is not None:
                self.publish("/scan", messages.laser_scan(reading.lidar, now, 1.0 / self.rates.scan_hz))
            self.record.poses.append(self._pose())
            self._check_outcome()
        if now >= self._due["odom"]:
            self._schedule("odom", self.rates.odom_hz, now)
            held = self.held if self.outcome is None and self.held_until_s > now else Twist(0.0, 0.0)
            self.publish("/odom", messages.odometry(self._pose(), held.linear_x, held.angular_z, now))
        if now >= self._due["camera"]:
            self._schedule("camera", self.rates.camera_hz, now)
            frame = self.environment.observe().camera
            if frame is not None:
                self.publish("/camera/image_raw/compressed", messages.compressed_image(frame, now))

    def _schedule(self, stream: str, hz: float, now: float) -> None:
        """The stream's next time: one period after the last (a steady rate), or after now when the
        loop fell more than a period behind (no burst to catch up)."""
        due = self._due[stream] + 1.0 / hz
        self._due[stream] = due if due > now else now + 1.0 / hz

    def _check_outcome(self) -> None:
        if self.outcome is None:
            outcome = self.environment.outcome()
            if outcome is not None:
                words = {Outcome.COMPLETED: ("target_reached", "the target was reached"),
                         Outcome.TIMEOUT: ("time_limit", "the room's time limit was reached")}
                kind, detail = words.get(outcome, ("outcome", outcome.value))
                self._finish(outcome, detail, kind)

    def _decide(self, result: ExecutionResult) -> None:
        self.publish("/safeembodai/events", messages.event("collision", self.sim_s, collision=result.collision,
                                                           hit=result.hit, detail=result.detail))
        self._finish(Outcome.INTERRUPTED, result.detail, None)

    def _finish(self, outcome: Outcome, detail: str, event: str | None, error_kind: ErrorKind | None = None) -> None:
        """Decide the outcome once: record it, and say it on the events topic (``event``: its kind;
        None when the caller said it already)."""
        if self.outcome is not None:
            return
        self.outcome = outcome
        self.held = Twist(0.0, 0.0)
        pose, truth = self._pose(), self._truth()
        picture = self.environment.trajectory_png(self.record.poses + [pose], outcome)
        wall = time.monotonic() - self._start_wall if self._start_wall is not None else 0.0
        self.record.finish(outcome, detail, pose, truth, self.sim_s, picture, wall, error_kind=error_kind)
        if event is not None:
            self.publish("/safeembodai/events", messages.event(event, self.sim_s, outcome=outcome.value, detail=detail))
        log.info("serve_robot.outcome", outcome=outcome.value, detail=detail, time_s=round(self.sim_s, 3))
