"""The robot's motion: kinematic, in small increments, checked for contact after each.

A ``straight`` or ``turn`` is cut into increments of at most ``step_mm`` / ``step_deg``. After
each, the Labbots advance by the same simulated time and pybullet's collision detection runs.
On contact, robot and Labbots go back to the last free state, the robot creeps forward by
bisection to within 1/16 of an increment of the contact, and the command stops: ``collided``
unless the body touched is the can. This gives exact distances and no penetration, far cheaper
than stepping 240 Hz physics (see ``docs/evidence/environments.md``).

Every collision says who moved into whom: ``self`` when the robot's own increment, with the
Labbots where they were before it, already touches the body; ``struck`` when it does not (a
Labbot ran into the robot: during think time, or while the robot turned on the spot -- a
cylinder that turns never hits anything -- or drove past). After a collision the robot is
wrecked: further commands are not executed.

Simulated time advances by distance / ``robot_speed_mm_s`` and angle / ``robot_turn_rate_deg_s``,
plus ``think_time_s`` once per observation: before the first command after it, or before the
next observation if no command came (the LLM thought, then answered nothing executable); with
``think_time_per_call``, once more for each retry's call (``another_call``). The
world (the Labbots) keeps moving while the LLM decides. A command stops early when the time
limit is spent.

Commands reach the environment already validated by the core's parser; a signal built around it
(``model_construct``) with a non-finite, non-positive or absurd value is still refused with an
:class:`~safeembodai_core.errors.EnvironmentError_` before pybullet sees it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, TypedDict

import numpy as np

from safeembodai_core.errors import EnvironmentError_
from safeembodai_core.models import ControlSignal, ExecutionResult, Straight, Turn
from safeembodai_core.models.records import Collision

from .quiet import silenced
from safeembodai_core.geometry.frames import wrap_deg

if TYPE_CHECKING:
    from .labbots import LabbotSwarm
    from .options import RoomOptions
    from .scene import Scene

#: Sanity bounds on one command, far beyond any actuation contract: larger values are refused.
MAX_COMMAND_MM = 100_000.0
MAX_COMMAND_DEG = 3600.0
_BISECTIONS = 4


class CollisionRecord(TypedDict, total=False):
    """A collision as the room keeps it: who moved into whom, what was hit and a one-line detail."""

    collision: Collision
    hit: str
    collision_detail: str


class _Moved(TypedDict, total=False):
    """How far a command moved the robot: the one :class:`ExecutionResult` field it sets."""

    distance_mm: float
    angle_deg: float


class KinematicMotion:
    """``execute`` for :class:`~.world.PybulletRoom` (which holds the state this mixin moves)."""

    if TYPE_CHECKING:  # the state this mixin moves, and the methods it calls, all PybulletRoom's
        kind: str
        options: RoomOptions
        scene: Scene
        swarm: LabbotSwarm | None
        xy: np.ndarray
        heading: float
        sim_time_s: float
        collided: bool
        collision_xy: np.ndarray | None
        collision: CollisionRecord
        _thinks: int

        def _take_think_s(self) -> float: ...

        def _require_reset(self) -> None: ...

        def _sync(self) -> None: ...

    def execute(self, signal: ControlSignal) -> ExecutionResult:
        self._require_reset()
        amount, per_unit_s, increment = self._check(signal)
        if self.collided:
            return ExecutionResult(stopped=True, detail=f"not executed: the robot had collided "
                                                        f"({self.collision.get('collision_detail', '')})")
        with silenced():
            if self._thinks:
                hit = self._wait(self._take_think_s())
                if hit is not None:
                    return self._result(signal, 0.0, hit, "while the robot stood still (think time)", standing=True)
            done, hit = self._move(signal, amount, per_unit_s, increment)
        return self._result(signal, done, hit,
                            "while the robot " + ("drove" if isinstance(signal, Straight) else "turned"))

    def _check(self, signal: ControlSignal) -> tuple[float, float, float]:
        o = self.options
        if isinstance(signal, Straight):
            value, limit, unit = signal.distance, MAX_COMMAND_MM, "mm"
            sign_ok = signal.direction in ("forward", "backward")
            rate, increment = 1.0 / o.robot_speed_mm_s, o.step_mm
        elif isinstance(signal, Turn):
            value, limit, unit = signal.angle, MAX_COMMAND_DEG, "deg"
            sign_ok = signal.direction in ("left", "right")
            rate, increment = 1.0 / o.robot_turn_rate_deg_s, o.step_deg
        else:
            raise EnvironmentError_(f"{self.kind}: unknown control signal {signal!r}; expected straight or turn")
        name = "distance" if unit == "mm" else "angle"
        if not isinstance(value, (int, float)) or not math.isfinite(value) or not 0 < value <= limit:
            raise EnvironmentError_(f"{self.kind}: refusing {signal.command} with {name}={value!r}: "
                                    f"it must be a finite number in (0, {limit:g}] {unit}")
        if not sign_ok:
            raise EnvironmentError_(f"{self.kind}: refusing {signal.command} with direction={signal.direction!r}")
        return float(value), rate, increment

    def _labbots(self) -> LabbotSwarm:
        """The trial's Labbots: ``reset`` draws them, and every caller has required a reset."""
        assert self.swarm is not None, "reset(seed) draws the Labbots"
        return self.swarm

    def _time_left(self) -> float:
        return max(self.options.max_sim_time_s - self.sim_time_s, 0.0)

    def _wait(self, seconds: float) -> int | None:
        """Let the world run for ``seconds`` with the robot standing still; the body hit, if any."""
        seconds = min(seconds, self._time_left())
        if seconds <= 0:
            return None
        swarm = self._labbots()
        if not len(swarm) or self.collided:  # after a collision the trial is over: time alone passes
            self.sim_time_s += seconds
            return None
        dt = self.options.step_mm / max(swarm.top_speed, 1e-9)  # the fastest Labbot moves step_mm a slice
        while seconds > 1e-12:
            slice_s = min(dt, seconds)
            saved = swarm.state()
            swarm.advance(slice_s, self.xy)
            self.sim_time_s += slice_s
            seconds -= slice_s
            self.scene.place_labbots(swarm.xy, swarm.heading)
            touched = self.scene.contacts()
            if touched:
                swarm.restore(saved)
                self.scene.place_labbots(swarm.xy, swarm.heading)
                return self._touch(touched, "struck")
        return None

    def _move(self, signal: ControlSignal, amount: float, per_unit_s: float,
              increment: float) -> tuple[float, int | None]:
        """Carry out ``amount`` (mm or deg) in increments; (amount done, body hit or None)."""
        straight = isinstance(signal, Straight)
        sign = ((1.0 if signal.direction == "forward" else -1.0) if isinstance(signal, Straight)
                else signal.signed_angle_deg / amount)
        pieces = max(1, math.ceil(amount / increment - 1e-9))
        piece = amount / pieces
        done = 0.0
        for _ in range(pieces):
            left = self._time_left()
            if left <= 0:
                break
            size = min(piece, left / per_unit_s)
            dt = size * per_unit_s
            swarm = self._labbots()
            start_xy, start_heading, saved = self.xy.copy(), self.heading, swarm.state()
            self._advance_robot(start_xy, start_heading, straight, sign * size)
            swarm.advance(dt, self.xy)
            self.sim_time_s = min(self.sim_time_s + dt, self.options.max_sim_time_s)
            self._sync()
            touched = self.scene.contacts()
            if touched:
                swarm.restore(saved)
                self._sync()  # the robot's increment alone, with the Labbots where they were
                own = {body for body in self.scene.contacts() if body != self.scene.can}
                free = self._bisect(start_xy, start_heading, straight, sign * size)
                return done + free, self._touch(own or touched, "self" if own else "struck")
            done += size
        return done, None

    def _advance_robot(self, xy: np.ndarray, heading: float, straight: bool, amount: float) -> None:
        if straight:
            rad = math.radians(heading)
            self.xy = xy + amount * np.array([math.cos(rad), math.sin(rad)])
            self.heading = heading
        else:
            self.xy = xy.copy()
            self.heading = wrap_deg(heading + amount)

    def _bisect(self, xy: np.ndarray, heading: float, straight: bool, amount: float) -> float:
        """The largest free part of ``amount`` (to ~1/16 of it), leaving the robot there."""
        low, high = 0.0, 1.0
        for _ in range(_BISECTIONS):
            middle = (low + high) / 2
            self._advance_robot(xy, heading, straight, amount * middle)
            self._sync()
            if self.scene.contacts():
                high = middle
            else:
                low = middle
        self._advance_robot(xy, heading, straight, amount * low)
        self._sync()
        return abs(amount) * low

    def _touch(self, touched: set[int], collision: Collision) -> int:
        """Record a contact (``collision``: who moved into whom); the body reported (an obstacle before the can)."""
        obstacles = sorted(body for body in touched if body != self.scene.can)
        if obstacles:
            self.collided = True
            self.collision_xy = self.xy.copy()
            self.collision = {"collision": collision}
            return obstacles[0]
        return self.scene.can

    def _collision_record(self, hit: int, when: str) -> CollisionRecord:
        """Who moved into whom, what was hit and a one-line detail; kept for later commands."""
        name = self.scene.names.get(hit, f"body {hit}")
        kind: Collision = self.collision.get("collision", "self")
        detail = f"struck by {name} {when}" if kind == "struck" else f"hit {name}"
        self.collision = {"collision": kind, "hit": self.scene.kinds.get(hit, "body"), "collision_detail": detail}
        return self.collision.copy()

    def _result(self, signal: ControlSignal, done: float, hit: int | None, when: str,
                standing: bool = False) -> ExecutionResult:
        straight = isinstance(signal, Straight)
        signed = done * (1.0 if not straight or signal.direction == "forward" else -1.0)
        values: _Moved
        if isinstance(signal, Straight):
            values = {"distance_mm": signed}
        else:
            values = {"angle_deg": math.copysign(done, signal.signed_angle_deg)}
        unit = "mm" if straight else "deg"
        if hit == self.scene.can:
            return ExecutionResult(stopped=True, hit="can", detail=f"stopped after {done:.0f} {unit}: touched the can",
                                   **values)
        if hit is not None:
            record = self._collision_record(hit, when)
            return ExecutionResult(stopped=True, collided=True, collision=record["collision"], hit=record["hit"],
                                   before_motion=standing,
                                   detail=f"stopped after {done:.0f} {unit}: {record['collision_detail']}", **values)
        requested = signal.distance if isinstance(signal, Straight) else signal.angle
        if done < requested - 1e-6:
            return ExecutionResult(stopped=True, detail=f"stopped after {done:.0f} {unit}: simulated-time limit of "
                                                        f"{self.options.max_sim_time_s:g} s reached", **values)
        return ExecutionResult(**values)
