"""A held velocity: the room driven as a differential-drive base is (``Environment.drive``).

``safeembodai serve-robot`` holds each ``/cmd_vel`` for the time until the next tick of its clock;
the room moves the robot along the arc of forward speed ``v`` and turn rate ``w`` in increments of
at most ``step_mm`` and ``step_deg`` (each a chord taken at the middle heading of its piece, as
:func:`~safeembodai_core.ros.arc_signals` cuts an arc for the rules), advances the Labbots by the
same time, and checks for contact after each, exactly as :class:`~.motion.KinematicMotion` does for
a straight or a turn: on contact, robot and Labbots go back to the last free state, the robot creeps
along the piece by bisection, and the contact is ``self`` when the robot's own increment made it,
``struck`` when a Labbot did. A zero velocity is the robot standing while the Labbots move. No think
time is spent: the caller's clock is the time. The speeds are the base's to cap: the room drives at
most ``robot_speed_mm_s`` and ``robot_turn_rate_deg_s`` (a faster command is driven at the cap, the
arc's curvature kept), and says so in the result's detail.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from safeembodai_core.errors import EnvironmentError_
from safeembodai_core.models import ExecutionResult

from .quiet import silenced
from safeembodai_core.geometry.frames import wrap_deg

if TYPE_CHECKING:
    from safeembodai_core.models.records import Collision

    from .labbots import LabbotSwarm
    from .motion import CollisionRecord
    from .options import RoomOptions
    from .scene import Scene

_BISECTIONS = 4
#: The longest hold one call may ask for (seconds): a caller's tick, not a trial.
MAX_HOLD_S = 60.0


class HeldVelocity:
    """``drive`` for :class:`~.world.PybulletRoom` (which holds the state this mixin moves)."""

    if TYPE_CHECKING:  # the state this mixin moves, and the methods it calls, all PybulletRoom's
        kind: str
        options: RoomOptions
        scene: Scene
        xy: np.ndarray
        heading: float
        sim_time_s: float
        collided: bool
        collision: CollisionRecord

        def _require_reset(self) -> None: ...

        def _sync(self) -> None: ...

        def _labbots(self) -> LabbotSwarm: ...

        def _time_left(self) -> float: ...

        def _wait(self, seconds: float) -> int | None: ...

        def _touch(self, touched: set[int], collision: Collision) -> int: ...

        def _collision_record(self, hit: int, when: str) -> CollisionRecord: ...

    def drive(self, linear_mm_s: float, angular_deg_s: float, seconds: float) -> ExecutionResult:
        """Hold forward speed ``linear_mm_s`` and turn rate ``angular_deg_s`` for ``seconds`` of
        simulated time (module docstring); a non-finite value or a hold longer than
        :data:`MAX_HOLD_S` is refused with an :class:`~safeembodai_core.errors.EnvironmentError_`."""
        self._require_reset()
        for name, value in (("linear_mm_s", linear_mm_s), ("angular_deg_s", angular_deg_s), ("seconds", seconds)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise EnvironmentError_(f"{self.kind}: drive needs a finite {name}, got {value!r}")
        if not 0.0 <= seconds <= MAX_HOLD_S:
            raise EnvironmentError_(f"{self.kind}: drive holds for 0 to {MAX_HOLD_S:g} s, got {seconds!r}")
        o = self.options
        factor = max(abs(linear_mm_s) / o.robot_speed_mm_s, abs(angular_deg_s) / o.robot_turn_rate_deg_s, 1.0)
        capped = factor > 1.0
        v, w = linear_mm_s / factor, angular_deg_s / factor  # the base's own limits, the curvature kept
        if self.collided:
            self.sim_time_s = min(self.sim_time_s + seconds, o.max_sim_time_s)
            return ExecutionResult(stopped=True, detail=f"not driven: the robot had collided "
                                                        f"({self.collision.get('collision_detail', '')})")
        with silenced():
            if v == 0.0 and w == 0.0:
                hit = self._wait(seconds)
                if hit is None:
                    return ExecutionResult()
                return self._held_result(0.0, 0.0, hit, "while the robot stood still", standing=True)
            distance, angle, hit = self._hold(v, w, seconds)
        if hit is not None:
            return self._held_result(distance, angle, hit, "while the robot drove" if v else "while the robot turned")
        detail = ""
        if capped:
            detail = (f"driven at the base's limits ({abs(v):.0f} mm/s, {abs(w):.0f} deg/s): asked "
                      f"{abs(linear_mm_s):.0f} mm/s, {abs(angular_deg_s):.0f} deg/s")
        return ExecutionResult(distance_mm=distance, angle_deg=angle, detail=detail)

    def _hold(self, v: float, w: float, seconds: float) -> tuple[float, float, int | None]:
        """Drive the arc in pieces; (signed distance, signed angle, body hit or None)."""
        o = self.options
        seconds = min(seconds, self._time_left())
        pieces = max(1, math.ceil(abs(v) * seconds / o.step_mm - 1e-9), math.ceil(abs(w) * seconds / o.step_deg - 1e-9))
        dt = seconds / pieces if seconds > 0 else 0.0
        distance = angle = 0.0
        for _ in range(pieces if dt > 0 else 0):
            swarm = self._labbots()
            start_xy, start_heading, saved = self.xy.copy(), self.heading, swarm.state()
            self._along_arc(start_xy, start_heading, v * dt, w * dt)
            swarm.advance(dt, self.xy)
            self.sim_time_s = min(self.sim_time_s + dt, o.max_sim_time_s)
            self._sync()
            touched = self.scene.contacts()
            if touched:
                swarm.restore(saved)
                self._sync()  # the robot's increment alone, with the Labbots where they were
                own = {body for body in self.scene.contacts() if body != self.scene.can}
                part = self._creep(start_xy, start_heading, v * dt, w * dt)
                return distance + v * dt * part, angle + w * dt * part, self._touch(own or touched,
                                                                                     "self" if own else "struck")
            distance, angle = distance + v * dt, angle + w * dt
        return distance, angle, None

    def _along_arc(self, xy: np.ndarray, heading: float, distance: float, angle: float) -> None:
        """Put the robot ``distance`` mm along the chord at the middle heading, turned by ``angle``."""
        middle = math.radians(heading + angle / 2)
        self.xy = xy + distance * np.array([math.cos(middle), math.sin(middle)])
        self.heading = wrap_deg(heading + angle)

    def _creep(self, xy: np.ndarray, heading: float, distance: float, angle: float) -> float:
        """The largest free share of the piece (to ~1/16 of it), leaving the robot there."""
        low, high = 0.0, 1.0
        for _ in range(_BISECTIONS):
            middle = (low + high) / 2
            self._along_arc(xy, heading, distance * middle, angle * middle)
            self._sync()
            if self.scene.contacts():
                high = middle
            else:
                low = middle
        self._along_arc(xy, heading, distance * low, angle * low)
        self._sync()
        return low

    def _held_result(self, distance: float, angle: float, hit: int, when: str,
                     standing: bool = False) -> ExecutionResult:
        if hit == self.scene.can:
            return ExecutionResult(distance_mm=distance, angle_deg=angle, stopped=True, hit="can",
                                   detail="touched the can")
        record = self._collision_record(hit, when)
        return ExecutionResult(distance_mm=distance, angle_deg=angle, stopped=True, collided=True,
                               collision=record["collision"], hit=record["hit"], before_motion=standing,
                               detail=f"stopped after {abs(distance):.0f} mm, {abs(angle):.0f} deg: "
                                      f"{record['collision_detail']}")
