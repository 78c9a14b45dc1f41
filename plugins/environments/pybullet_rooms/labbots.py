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
alone: where blind Labbots are is a function of simulated time only, never of how the robot's
commands were cut into increments, so two arms that spend the same simulated time meet the
same blind Labbots. Sensing Labbots react to the robot, so they stay a function of the seed
and of the robot's path: two arms whose robots went different ways meet different Labbots.
"""

from __future__ import annotations

import math
from typing import Callable

import numpy as np

CLEARANCE_MM = 30.0
TICK_S = 0.05

#: ``sense(xy, headings_deg, robot_xy)``: per Labbot, the free distance (mm) each sensor reads.
RangeSense = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


class LabbotSwarm:
    """Positions (mm) and headings (deg) of every Labbot, and how they move."""

    def __init__(self, options, xy: np.ndarray, headings_deg: np.ndarray, obstacles: np.ndarray,
                 seed: int, sense: RangeSense | None = None) -> None:
        self.o = options
        self.sense = sense
        self.radius = float(getattr(options, "labbot_radius_mm", 0.0))
        self.xy = np.array(xy, dtype=float).reshape(-1, 2)  # mm, world frame
        self.heading = np.array(headings_deg, dtype=float).reshape(-1)  # deg, CCW from +x
        self.turning = np.zeros(len(self.xy))  # -1 / +1 while turning away from something, else 0
        self._statics = [tuple(map(float, row)) for row in np.asarray(obstacles, dtype=float).reshape(-1, 3)]
        self.seed = int(seed)
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
        while (self.ticks + 1) * TICK_S <= self.clock_s + 1e-9:
            self._tick(robot_xy, np.random.default_rng([self.seed, self.ticks]))
            self.ticks += 1

    def _tick(self, robot_xy: np.ndarray, rng: np.random.Generator) -> None:
        o, dt = self.o, TICK_S
        avoid = (float(robot_xy[0]), float(robot_xy[1])) if o.labbots_avoid_robot else None
        drift = rng.normal(0.0, o.labbot_wander_deg * math.sqrt(dt), size=len(self)).tolist()
        sides = np.where(rng.random(size=len(self)) < 0.5, -1.0, 1.0).tolist()
        xs, ys = self.xy[:, 0].tolist(), self.xy[:, 1].tolist()
        turning = self.turning.tolist()
        # the heading each Labbot takes this tick: turning on, or drifting
        headings = [h + (t * o.labbot_turn_rate_deg_s * dt if t else d)
                    for h, t, d in zip(self.heading.tolist(), turning, drift)]
        seen = self._seen(np.array(headings), robot_xy)
        step, lookahead = o.labbot_speed_mm_s * dt, o.labbot_speed_mm_s * dt + o.labbot_lookahead_mm
        for i in range(len(xs)):
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
            headings[i] = (headings[i] + 180.0) % 360.0 - 180.0
        self.xy = np.column_stack((xs, ys))
        self.heading, self.turning = np.array(headings), np.array(turning)
        self.track.append(self.xy.copy())

    def _seen(self, headings: np.ndarray, robot_xy: np.ndarray) -> list[float]:
        """Per Labbot: 0 if its sensors read nothing within range, else the side to turn to: +1
        (left) or -1 (right), away from the nearer side reading; 2 if only the sensor straight
        ahead reads something (then the side is drawn at random)."""
        if self.sense is None:
            return [0.0] * len(self)
        ranges = np.asarray(self.sense(self.xy, headings, robot_xy), dtype=float)  # (L, sensors)
        reach = self.o.labbot_sensor_range_mm
        seen = []
        for row in ranges:
            if not (row < reach).any():
                seen.append(0.0)
                continue
            left, right = row[1::2].min(), row[2::2].min()  # sensors: ahead, then left/right pairs
            seen.append(2.0 if left == right else -1.0 if left < right else 1.0)
        return seen
