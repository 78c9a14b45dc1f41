"""Labbots: the moving obstacles of ``DO`` and ``MO``.

Each Labbot cruises at a constant speed while its heading drifts at random (a random walk of
``labbot_wander_deg`` per square-root second). Before each move it checks that both its next
position and a point ``labbot_lookahead_mm`` further ahead keep a clearance from the walls,
the soccer balls, the can and the other Labbots (its bumper: it knows the room); if not, it
stops and turns on the spot (to a side drawn at random, kept until the way ahead is clear).

With ``labbot_sensing`` (the default) a Labbot also carries five distance sensors across its
front (see :class:`~.sensors.LabbotRangeSensors`): while any of them reads something within
``labbot_sensor_range_mm`` -- a wall, a ball, the can, another Labbot or the robot -- it does
not advance but turns on the spot away from the nearer side until all read clear, like a
wandering robot with its own sensors. Blind Labbots (``labbot_sensing: false``) do not see the
robot unless ``labbots_avoid_robot`` is set (a clearance check against its true position):
they can run into it, and that ends the trial as ``interrupted``.

The motion is plain numpy (the sensors are a callable the world hands in); the world copies the
positions into pybullet, where the robot's contact checks see them. Labbots move on a fixed
clock of ``TICK_S`` ticks, and tick k draws from a generator seeded by (the swarm's seed, k)
alone (``np.random.default_rng([seed, k])``, made cheaply by :class:`~.streams.TickStreams`):
where blind Labbots are is a function of simulated time only, never of how the robot's
commands were cut into increments, so two arms that spend the same simulated time meet the
same blind Labbots. Sensing Labbots react to the robot, so they stay a function of the seed
and of the robot's path: two arms whose robots went different ways meet different Labbots.

Every Labbot has its own speed, wander, sensing, yielding (``labbots_avoid_robot``) and
stop-and-go: by default all take the room's scalar options; with a mover family
(:mod:`.movers`) each takes its drawn :class:`~.movers.Mover`. A stop-and-go Labbot alternates
go and stop phases whose lengths (whole ticks) and leaving headings come from a generator seeded
by (the swarm's seed, :data:`STOP_STREAM`, the Labbot's index, the cycle) alone, so where it stands
and when it leaves are a function of simulated time only, like the blind Labbots' wandering.
While stopped it stands still (no drift, no turning); on the first tick after a stop it takes the
new heading, drawn uniformly in [-180, 180), and moves on from there as any Labbot does.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Callable, Sequence

import numpy as np
from safeembodai_core.geometry.frames import wrap_deg

from .streams import TickStreams

if TYPE_CHECKING:
    from .movers import Range

CLEARANCE_MM = 30.0
TICK_S = 0.05
#: Label of the stop-and-go streams: ``default_rng([seed, STOP_STREAM, labbot, cycle])``.
STOP_STREAM = 0x5709

#: Room the sensors' skipping keeps beyond their reach (mm): far more than any ray-cast tolerance.
SENSE_SLACK_MM = 20.0

#: ``sense(xy, headings_deg, robot_xy)``: per Labbot, the free distance (mm) each sensor reads.
RangeSense = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


class LabbotSwarm:
    """Positions (mm) and headings (deg) of every Labbot, and how they move."""

    def __init__(self, options, xy: np.ndarray, headings_deg: np.ndarray, obstacles: np.ndarray,
                 seed: int, sense: RangeSense | None = None, movers: Sequence | None = None,
                 sense_reads_room: bool = False) -> None:
        """``sense_reads_room``: ``sense`` reads only this room's bodies (its walls, the robot,
        ``obstacles`` and the other Labbots), so a tick with none of them in reach may skip it."""
        self.o = options
        self.sense = sense
        self._may_skip_sense = bool(sense_reads_room)
        self.radius = float(getattr(options, "labbot_radius_mm", 0.0))
        self.xy = np.array(xy, dtype=float).reshape(-1, 2)  # mm, world frame
        self.heading = np.array(headings_deg, dtype=float).reshape(-1)  # deg, CCW from +x
        self.turning = np.zeros(len(self.xy))  # -1 / +1 while turning away from something, else 0
        n = len(self.xy)
        if movers is None:  # the room's scalar options, for every Labbot
            movers = [None] * n
            speed = [float(getattr(options, "labbot_speed_mm_s", 0.0))] * n
            wander = [float(getattr(options, "labbot_wander_deg", 0.0))] * n
            self.sensing = [bool(getattr(options, "labbot_sensing", False))] * n
            self.yielding = [bool(getattr(options, "labbots_avoid_robot", False))] * n
            self.stop_and_go = [False] * n
        else:
            if len(movers) != n:
                raise ValueError(f"{len(movers)} movers' parameters for {n} Labbots")
            speed = [float(m.speed_mm_s) for m in movers]
            wander = [float(m.wander_deg) for m in movers]
            self.sensing = [bool(m.sensing) for m in movers]
            self.yielding = [bool(m.yielding) for m in movers]
            self.stop_and_go = [bool(m.stop_and_go) for m in movers]
        self.speed = np.array(speed, dtype=float)  # mm/s, per Labbot
        self.wander = np.array(wander, dtype=float)  # deg per sqrt(s), per Labbot
        self.top_speed = float(self.speed.max()) if n else 0.0
        self._speeds = self.speed.tolist()
        self._drift_scale = self.wander * math.sqrt(TICK_S)
        self._any_stop_and_go = any(self.stop_and_go)
        # stop-and-go: per Labbot, the (go, stop) duration ranges and the cycles drawn so far
        self._phases: list[tuple[Range, Range] | None] = [(m.go_s, m.stop_s) if stops else None
                                                          for m, stops in zip(movers, self.stop_and_go)]
        self._cycles: list[list[tuple[int, int, float]]] = [[] for _ in range(n)]
        self._statics = [tuple(map(float, row)) for row in np.asarray(obstacles, dtype=float).reshape(-1, 3)]
        self.seed = int(seed)
        self._streams: TickStreams | None = None  # default_rng([seed, tick]), made cheaply: built at the first tick
        self.clock_s = 0.0  # simulated time this swarm has been given
        self.ticks = 0  # ticks moved so far
        self.track: list[np.ndarray] = [self.xy.copy()]

    def __len__(self) -> int:
        return len(self.xy)

    def state(self) -> tuple:
        return self.xy.copy(), self.heading.copy(), self.turning.copy(), self.clock_s, self.ticks, len(self.track)

    def restore(self, state: tuple) -> None:
        xy, heading, turning, self.clock_s, self.ticks, kept = state
        self.xy, self.heading, self.turning = xy.copy(), heading.copy(), turning.copy()
        del self.track[kept:]

    def _clear(self, index: int, x: float, y: float, xs: list[float], ys: list[float],
               robot: tuple[float, float] | None) -> bool:
        """Would Labbot ``index`` at (x, y) keep its clearance? (plain floats: a handful of bodies)"""
        reach = self.radius + CLEARANCE_MM
        if not (reach <= x <= self.o.room_mm - reach and reach <= y <= self.o.room_mm - reach):
            return False
        for ox, oy, radius in self._statics:
            if math.hypot(ox - x, oy - y) - radius < reach:
                return False
        for other, (ox, oy) in enumerate(zip(xs, ys)):
            if other != index and math.hypot(ox - x, oy - y) < reach + self.radius:
                return False
        return robot is None or math.hypot(robot[0] - x, robot[1] - y) >= reach + self.o.robot_radius_mm

    def advance(self, dt: float, robot_xy: np.ndarray) -> None:
        """Let ``dt`` simulated seconds pass: every whole tick reached in that time is moved."""
        if dt <= 0 or not len(self):
            return
        self.clock_s += dt
        if self._streams is None:
            self._streams = TickStreams(self.seed)
        while (self.ticks + 1) * TICK_S <= self.clock_s + 1e-9:
            self._tick(robot_xy, self._streams.generator(self.ticks))
            self.ticks += 1

    def _tick(self, robot_xy: np.ndarray, rng: np.random.Generator) -> None:
        o, dt = self.o, TICK_S
        n = len(self.heading)
        robot = (float(robot_xy[0]), float(robot_xy[1]))
        # one draw of n normals, each scaled by its Labbot's wander: rng.normal(0.0, scale, n) computes
        # 0.0 + scale * z from the same standard normals, bit for bit, at a fraction of the cost
        drift = (0.0 + self._drift_scale * rng.standard_normal(n)).tolist()
        sides = [-1.0 if u < 0.5 else 1.0 for u in rng.random(size=n).tolist()]
        xs, ys = self.xy[:, 0].tolist(), self.xy[:, 1].tolist()
        turning = self.turning.tolist()
        current = self.heading.tolist()
        stopped = [False] * n
        if self._any_stop_and_go:
            for i, stops in enumerate(self.stop_and_go):
                if stops:
                    stopped[i], leave = self._phase(i, self.ticks)
                    if leave is not None:  # the first tick after a stop: off at a new heading
                        current[i], turning[i] = leave, 0.0
        # the heading each Labbot takes this tick: turning on, or drifting (standing still while stopped)
        headings = [h if halt else h + (t * o.labbot_turn_rate_deg_s * dt if t else d)
                    for h, t, d, halt in zip(current, turning, drift, stopped)]
        seen = self._seen(headings, robot_xy)
        lookahead_mm = o.labbot_lookahead_mm
        for i in range(n):
            if stopped[i]:
                continue
            avoid = robot if self.yielding[i] else None
            step = self._speeds[i] * dt
            lookahead = step + lookahead_mm
            rad = math.radians(headings[i])
            cos, sin = math.cos(rad), math.sin(rad)
            if turning[i]:
                if not seen[i] and self._clear(i, xs[i] + lookahead * cos, ys[i] + lookahead * sin, xs, ys, avoid):
                    turning[i] = 0.0
            else:
                nx, ny = xs[i] + step * cos, ys[i] + step * sin
                if (not seen[i] and self._clear(i, nx, ny, xs, ys, avoid)
                        and self._clear(i, xs[i] + lookahead * cos, ys[i] + lookahead * sin, xs, ys, avoid)):
                    xs[i], ys[i] = nx, ny
                else:
                    turning[i] = seen[i] if abs(seen[i]) == 1.0 else sides[i]
            headings[i] = wrap_deg(headings[i])
        self.xy = np.array((xs, ys)).T.copy()
        self.heading, self.turning = np.array(headings), np.array(turning)
        self.track.append(self.xy.copy())

    def _phase(self, index: int, tick: int) -> tuple[bool, float | None]:
        """Stop-and-go Labbot ``index`` at ``tick``: (stopped?, the heading it leaves at if this
        is the first tick after a stop, else None). Cycle c is a go phase then a stop phase, their
        lengths (whole ticks, at least one) and the leaving heading drawn from the stream (seed,
        :data:`STOP_STREAM`, index, c) alone."""
        cycles = self._cycles[index]
        while not cycles or cycles[-1][1] <= tick:
            phases = self._phases[index]
            assert phases is not None  # asked only of a stop-and-go Labbot, which has its phases
            (go_lo, go_hi), (stop_lo, stop_hi) = phases
            rng = np.random.default_rng([self.seed, STOP_STREAM, index, len(cycles)])
            go_u, stop_u, heading_u = rng.random(3).tolist()
            go = max(1, round((go_lo + (go_hi - go_lo) * go_u) / TICK_S))
            stop = max(1, round((stop_lo + (stop_hi - stop_lo) * stop_u) / TICK_S))
            start = (cycles[-1][1] if cycles else 0) + go
            cycles.append((start, start + stop, -180.0 + 360.0 * heading_u))
        for number, (start, end, _) in enumerate(cycles):
            if tick < end:
                leave = cycles[number - 1][2] if number and tick == cycles[number - 1][1] else None
                return start <= tick, leave
        raise AssertionError("unreachable: the cycles reach past tick")

    def stopped(self, tick: int | None = None) -> list[bool]:
        """Per Labbot: is it in a stop phase at ``tick`` (default: the next tick to move)?"""
        tick = self.ticks if tick is None else tick
        return [stops and self._phase(i, tick)[0] for i, stops in enumerate(self.stop_and_go)]

    def _seen(self, headings: Sequence[float], robot_xy: np.ndarray) -> list[float]:
        """Per Labbot: 0 if its sensors read nothing within range (or it has none), else the side
        to turn to: +1 (left) or -1 (right), away from the nearer side reading; 2 if only the
        sensor straight ahead reads something (then the side is drawn at random)."""
        if self.sense is None or not any(self.sensing) or (self._may_skip_sense and self._out_of_reach(robot_xy)):
            return [0.0] * len(self)
        ranges = np.asarray(self.sense(self.xy, np.array(headings, dtype=float), robot_xy), dtype=float)  # (L, sensors)
        reach = self.o.labbot_sensor_range_mm
        seen = []
        for row, sensing in zip(ranges.tolist(), self.sensing):
            if not sensing or min(row) >= reach:
                seen.append(0.0)
                continue
            left, right = min(row[1::2]), min(row[2::2])  # sensors: ahead, then left/right pairs
            seen.append(2.0 if left == right else -1.0 if left < right else 1.0)
        return seen

    def _out_of_reach(self, robot_xy: np.ndarray) -> bool:
        """True when no body lies within :data:`SENSE_SLACK_MM` more than any sensing Labbot's sensor
        reach of its centre: then every sensor reads nothing, and the ray cast (the bulk of a tick's
        cost) can be skipped with the same result. A bound on distance alone, whatever the rays'
        directions: the sensors are cast only when something is near."""
        reach = self.radius + self.o.labbot_sensor_range_mm + SENSE_SLACK_MM
        room = self.o.room_mm
        robot_x, robot_y, robot_r = float(robot_xy[0]), float(robot_xy[1]), self.o.robot_radius_mm
        xs, ys = self.xy[:, 0].tolist(), self.xy[:, 1].tolist()
        for i, (x, y) in enumerate(zip(xs, ys)):
            if not self.sensing[i]:
                continue
            if x < reach or y < reach or room - x < reach or room - y < reach:
                return False
            if math.hypot(robot_x - x, robot_y - y) - robot_r < reach:
                return False
            for ox, oy, radius in self._statics:
                if math.hypot(ox - x, oy - y) - radius < reach:
                    return False
            for j, (ox, oy) in enumerate(zip(xs, ys)):
                if j != i and math.hypot(ox - x, oy - y) - self.radius < reach:
                    return False
        return True
