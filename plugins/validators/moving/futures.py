"""Where a mover may be later: a fan of wandering futures drawn from what the scans showed.

A mover's course 5 to 15 s ahead is not a straight line: Labbots (and people, and other robots)
drift, stop and turn. :class:`WanderingFutures` draws ``count`` possible courses for a mover
(:class:`~.tracking.Blob`): each starts where the scan saw it, at the speed the two scans gave,
on a heading drawn around the measured one, and then drifts as a random walk of ``wander_deg``
per square-root second. The measured speed is a chord's (the straight line between two scans),
shorter than the path of a mover that turned or stopped on the way. With ``cruise_speed_mm_s``
(movers known to move at that speed when they move) every course but course 0 runs at the larger
of the measured and the cruising speed, and a chord shorter than a wandering cruiser's reaches in
all but ``TURN_QUANTILE`` (5%) of cases (:func:`~.tracking.chord_share_quantile`) says the mover
turned or stopped for part of the span: that share of the courses -- 1 - measured / that chord
speed -- starts on a heading drawn evenly all the way round (where it goes after a turn is
unknown), the others around the chord; a chord shorter than ``still_mm`` gives no direction, and
every course but course 0 is fanned.
The spread of the starting heading is the random walk's over the span the velocity was measured
on (a chord between two scans ``span_s`` apart points along the mean heading of that span, whose
difference from the final heading has variance ``wander**2 * span / 3``). A mover of unknown
velocity (where it was was not seen) gets courses fanned evenly all the way round at
``unknown_speed_mm_s``.

Course 0 is always the measured course itself (no wander, the measured speed), so even one
course is the straight-course prediction; with ``wander_deg`` 0 (and no top speed) every course
of a mover with a velocity is that straight line. All movers share the same draws (their
courses wander alike); the share judged is per mover, so that does not matter. The draws are
fixed by ``seed`` (the same check gives the same verdict, whatever was checked before), and the
noise of later times never changes the courses' earlier parts, so a shorter motion is judged on
the same futures as a longer one.
Given the scan's standing returns (:class:`~.walls.Walls`, option ``walls``), a course turns where
it would meet one, to a heading drawn among those that stay clear; without them, courses pass through
walls (the rule does not map the room): one that would turn at a wall is predicted beyond it, away
from the robot -- a failure mode ``docs/validation.md`` lists.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .tracking import Blob, chord_share_quantile
from .walls import HEADINGS, Walls

_CHUNK = 128  # columns of noise drawn at a time (each chunk from its own seeded generator)
#: courses turning at walls are stepped this many steps at a time (kept for the plan's later checks)
_WALLED_STEPS = 64
#: at most this many turns at walls are followed per check (a course still meeting one after: as drawn)
_MAX_TURNS = 32
#: a chord shorter than this quantile of a wandering cruiser's says the mover turned or stopped
TURN_QUANTILE = 0.05


@dataclass(frozen=True)
class WanderSettings:
    wander_deg: float = 25.0
    count: int = 64
    step_s: float = 0.1
    unknown_speed_mm_s: float = 150.0
    cruise_speed_mm_s: float | None = None
    still_mm: float = 100.0  # with a cruising speed: a chord shorter than this gives no direction
    seed: int = 0


class WanderingFutures:
    """Possible courses of movers, on a time grid of ``step_s`` from the scan."""

    def __init__(self, settings: WanderSettings) -> None:
        self.s = settings
        self._noise = np.zeros((settings.count, 0))
        self._uniform = np.zeros((settings.count, 0))  # which free heading a course takes at a wall
        self._walled: dict[tuple[int, int], tuple] = {}  # (mover, walls) -> courses on the step grid
        # with a cruising speed: which courses start after a turn (draw below the turned share), and
        # on which heading (each its own stream; course 0 is never turned)
        turns = np.random.default_rng([settings.seed, 2**32 - 1]).random((2, settings.count))
        self._turn_draw, self._turn_heading = turns[0], (turns[1] * 2.0 - 1.0) * math.pi
        self._turn_draw[0] = 1.0

    def _chunked(self, name: str, columns: int, draw: Callable[[int], np.ndarray]) -> np.ndarray:
        """The draws kept in attribute ``name``, grown by ``draw(chunk)`` (count, _CHUNK) to at least
        ``columns`` columns: column j is the same whatever is asked later."""
        kept = getattr(self, name)
        have, need = kept.shape[1] // _CHUNK, -(-columns // _CHUNK)
        if need > have:
            kept = np.concatenate([kept, *(draw(chunk) for chunk in range(have, need))], axis=1)
            setattr(self, name, kept)
        return kept

    def _normals(self, columns: int) -> np.ndarray:
        """Standard normal draws, (count, columns), each chunk from its own seeded generator."""
        s = self.s
        noise = self._chunked("_noise", columns,
                              lambda chunk: np.random.default_rng([s.seed, chunk]).standard_normal((s.count, _CHUNK)))
        noise[0] = 0.0  # course 0 is the measured course: no wander, the measured speed
        return noise[:, :columns]

    def _uniforms(self, columns: int) -> np.ndarray:
        """Uniform draws in [0, 1), (count, columns), from a stream of their own."""
        s = self.s
        stream = 2**32 - 2  # the turns' own stream (the starting headings' is 2**32 - 1)
        uniform = self._chunked("_uniform", columns,
                                lambda chunk: np.random.default_rng([s.seed, stream, chunk]).random((s.count, _CHUNK)))
        return uniform[:, :columns]

    def wander_deg(self, blob: Blob) -> float:
        """The mover's wander: what its track taught (:mod:`.learning`), else the settings'."""
        return self.s.wander_deg if blob.wander_deg is None else blob.wander_deg

    def cruise_mm_s(self, blob: Blob) -> float | None:
        """The mover's cruising speed: what its track taught, else the settings' (None: not known)."""
        return self.s.cruise_speed_mm_s if blob.cruise_mm_s is None else blob.cruise_mm_s

    def turned_share(self, blob: Blob) -> float:
        """With a cruising speed: the share of a mover's courses that start after a turn, 1 - the
        measured speed over the chord speed a cruising, wandering mover reaches in all but
        ``TURN_QUANTILE`` of cases (so a mover that only wandered is read as turned that rarely);
        1 for a chord shorter than ``still_mm``; 0 without a cruising speed, or for an unknown velocity."""
        s = self.s
        cruise = self.cruise_mm_s(blob)
        if cruise is None or blob.velocity is None:
            return 0.0
        measured = float(np.hypot(*blob.velocity))
        if measured * blob.span_s < s.still_mm:
            return 1.0
        least = cruise * chord_share_quantile(self.wander_deg(blob), blob.span_s, TURN_QUANTILE)
        return float(np.clip(1.0 - measured / least, 0.0, 1.0)) if least > 0 else 0.0

    def _turned(self, blob: Blob) -> np.ndarray:
        """Which of the mover's courses start on a heading drawn all the way round (never course 0)."""
        return self._turn_draw < self.turned_share(blob)

    def turned_courses(self, blob: Blob) -> int:
        """How many of the mover's courses start on a heading drawn all the way round."""
        return int(np.count_nonzero(self._turned(blob)))

    def at(self, blob: Blob, times: np.ndarray, walls: Walls | None = None) -> np.ndarray:
        """The courses' centres (count, len(times), 2) at ``times`` (s after the scan, >= 0)."""
        return self.courses(blob, times, walls)[0]

    def courses(self, blob: Blob, times: np.ndarray, walls: Walls | None = None) -> tuple[np.ndarray, np.ndarray]:
        """The courses' centres (count, len(times), 2) and headings (count, len(times), radians);
        with ``walls``, courses turn where they would meet a standing return."""
        s = self.s
        times = np.maximum(np.asarray(times, dtype=float), 0.0)
        steps = int(math.ceil(float(times.max(initial=0.0)) / s.step_s)) + 1
        if walls is not None:
            grid, heading, step = self._walled_grid(blob, steps, walls)
        else:
            grid, heading, step = self._grid(blob, steps)
        index = np.minimum((times // s.step_s).astype(int), steps - 1)
        within = (times - index * s.step_s)[None, :, None] / s.step_s
        return grid[:, index] + within * step[:, index], heading[:, index]

    def _start(self, blob: Blob, noise: np.ndarray) -> tuple[np.ndarray, np.ndarray | float]:
        """Each course's starting heading (radians) and speed (mm/s; an array with a cruising speed)."""
        s = self.s
        measured = 0.0 if blob.velocity is None else float(np.hypot(*blob.velocity))
        cruise = self.cruise_mm_s(blob)
        if blob.velocity is None:
            # no velocity: courses fanned evenly all the way round
            return np.linspace(-math.pi, math.pi, s.count, endpoint=False), s.unknown_speed_mm_s
        spread = math.radians(self.wander_deg(blob)) * math.sqrt(max(blob.span_s, 0.0) / 3.0)
        start = math.atan2(blob.velocity[1], blob.velocity[0]) + spread * noise[:, 0]
        if cruise is None:
            return start, measured
        speed = np.full(s.count, max(measured, cruise))
        speed[0] = measured  # course 0: the measured course
        return np.where(self._turned(blob), self._turn_heading, start), speed

    def _walled_grid(self, blob: Blob, steps: int, walls: Walls) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Like :meth:`_grid`, with each course turned where its next step would bring the disc onto
        a standing return (from a clear position: a course that starts against a wall leaves it as
        drawn), to a heading drawn evenly among the :data:`~.walls.HEADINGS` whose next step is
        clear; with none clear it stands from there on. A turn adds the same angle to the rest of
        the course's headings (its own wander goes on), so the courses are stepped bounce by bounce,
        every course at once. Kept per mover and walls: the plan's straights are judged on the same
        courses."""
        key = (id(blob), id(walls))
        kept = self._walled.get(key)
        if kept is not None and kept[0] is blob and kept[1] is walls and kept[4].shape[1] >= steps:
            return kept[2], kept[3], kept[4]
        s = self.s
        steps = -(-steps // _WALLED_STEPS) * _WALLED_STEPS  # room for the plan's later straights
        grid, heading, step = self._grid(blob, steps)  # fresh arrays: (count, steps + 1, 2), (count, steps), ...
        uniform = self._uniforms(steps)
        stride = np.hypot(step[:, :1, 0], step[:, :1, 1])  # (count, 1): each course's distance per step
        around = np.linspace(0.0, 2 * math.pi, HEADINGS, endpoint=False)
        wall = walls.blocked(grid, blob.radius_mm)  # (count, steps + 1)
        moves, points = np.arange(steps), np.arange(steps + 1)
        after = np.zeros(s.count, dtype=int)  # each course is checked from this step on
        rows = np.arange(s.count)
        for _ in range(_MAX_TURNS):
            meets = wall[:, 1:] & ~wall[:, :-1] & (moves[None, :] >= after[:, None])  # (count, steps)
            hit = rows[meets.any(axis=1)]
            if not hit.size:
                break
            m = meets[hit].argmax(axis=1)  # the step whose move would meet the wall
            here = grid[hit, m]
            options = heading[hit, m][:, None] + around[None, :]
            ahead = here[:, None, :] + stride[hit][:, :, None] * np.stack((np.cos(options), np.sin(options)), -1)
            clear = ~walls.blocked(ahead, blob.radius_mm)
            free = clear.sum(axis=1)
            pick = np.minimum((uniform[hit, m] * free).astype(int), np.maximum(free - 1, 0))
            chosen = np.argmax(np.cumsum(clear, axis=1) > pick[:, None], axis=1)
            turn = np.where(free > 0, options[np.arange(len(hit)), chosen] - heading[hit, m], 0.0)
            later = moves[None, :] >= m[:, None]
            heading[hit] += np.where(later, turn[:, None], 0.0)
            moved = stride[hit][:, :, None] * np.stack((np.cos(heading[hit]), np.sin(heading[hit])), -1)
            moved = np.where(((free == 0)[:, None] & later)[..., None], 0.0, moved)  # nowhere clear: it stands
            step[hit] = np.where(later[..., None], moved, step[hit])
            # from the turn on: where it was, plus the steps taken since (an exclusive running sum)
            taken = np.concatenate((np.zeros((len(hit), 1, 2)),
                                    np.cumsum(np.where(later[..., None], moved, 0.0), axis=1)), axis=1)
            since = points[None, :] >= m[:, None]
            grid[hit] = np.where(since[..., None], here[:, None, :] + taken, grid[hit])
            wall[hit] = np.where(since, walls.blocked(grid[hit], blob.radius_mm), wall[hit])
            after[hit] = np.where(free > 0, m + 1, steps)
        kept = (blob, walls, grid, heading, step)
        if len(self._walled) > 64:
            self._walled.clear()
        self._walled[key] = kept
        return grid, heading, step

    def _grid(self, blob: Blob, steps: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The courses on the step grid: centres (count, steps + 1, 2), headings (count, steps) and
        the step taken from each point (count, steps, 2)."""
        s = self.s
        noise = self._normals(steps + 1)
        start, speed = self._start(blob, noise)
        if np.ndim(speed):
            speed = np.asarray(speed).reshape(-1, 1, 1)
        wander = self.wander_deg(blob)
        drift = math.radians(wander) * math.sqrt(s.step_s) * noise[:, 1:steps]
        heading = start[:, None] + np.concatenate((np.zeros((s.count, 1)), np.cumsum(drift, axis=1)), axis=1)
        step = speed * s.step_s * np.stack((np.cos(heading), np.sin(heading)), axis=-1)  # (count, steps, 2)
        grid = blob.centre + np.concatenate((np.zeros((s.count, 1, 2)), np.cumsum(step, axis=1)), axis=1)
        return grid, heading, step


def yielding(where: np.ndarray, heading: np.ndarray, robot: np.ndarray, robot_radius_mm: float,
             mover_radius_mm: float, range_mm: float, half_angle_deg: float) -> np.ndarray:
    """The courses of a mover that stops for the robot: from the first moment the robot's body lies
    within ``range_mm`` of the mover's rim and within ``half_angle_deg`` of its heading (what the
    rooms' Labbots' front sensors see), the course stays where it is (a Labbot turns away on the
    spot). ``where`` (count, T, 2) and ``heading`` (count, T) at the moments ``robot`` (T, 2) gives;
    a ``range_mm`` of 0 is a mover that never yields."""
    if range_mm <= 0:
        return where
    offset = robot[None] - where
    gap = np.hypot(offset[..., 0], offset[..., 1]) - robot_radius_mm - mover_radius_mm
    off_course = np.abs((np.arctan2(offset[..., 1], offset[..., 0]) - heading + np.pi) % (2 * np.pi) - np.pi)
    sees = (gap < range_mm) & (off_course <= math.radians(half_angle_deg))
    first = np.where(sees.any(axis=1), sees.argmax(axis=1), where.shape[1])
    held = np.minimum(np.arange(where.shape[1])[None, :], first[:, None])
    return np.take_along_axis(where, held[..., None], axis=1)
