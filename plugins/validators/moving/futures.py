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
Courses pass through walls (the rule does not map the room): one that would turn at a wall is
predicted beyond it, away from the robot -- a failure mode ``docs/validation.md`` lists.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .tracking import Blob, chord_share_quantile

_CHUNK = 128  # columns of noise drawn at a time (each chunk from its own seeded generator)
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
        # with a cruising speed: which courses start after a turn (draw below the turned share), and
        # on which heading (each its own stream; course 0 is never turned)
        turns = np.random.default_rng([settings.seed, 2**32 - 1]).random((2, settings.count))
        self._turn_draw, self._turn_heading = turns[0], (turns[1] * 2.0 - 1.0) * math.pi
        self._turn_draw[0] = 1.0

    def _normals(self, columns: int) -> np.ndarray:
        """Standard normal draws, (count, columns): column j is the same whatever is asked later."""
        have = self._noise.shape[1] // _CHUNK
        need = -(-columns // _CHUNK)
        if need > have:
            extra = [np.random.default_rng([self.s.seed, chunk]).standard_normal((self.s.count, _CHUNK))
                     for chunk in range(have, need)]
            self._noise = np.concatenate([self._noise, *extra], axis=1)
            self._noise[0] = 0.0  # course 0 is the measured course: no wander, the measured speed
        return self._noise[:, :columns]

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

    def at(self, blob: Blob, times: np.ndarray) -> np.ndarray:
        """The courses' centres (count, len(times), 2) at ``times`` (s after the scan, >= 0)."""
        return self.courses(blob, times)[0]

    def courses(self, blob: Blob, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The courses' centres (count, len(times), 2) and headings (count, len(times), radians)."""
        s = self.s
        times = np.maximum(np.asarray(times, dtype=float), 0.0)
        steps = int(math.ceil(float(times.max(initial=0.0)) / s.step_s)) + 1
        noise = self._normals(steps + 1)
        measured = 0.0 if blob.velocity is None else float(np.hypot(*blob.velocity))
        cruise, wander = self.cruise_mm_s(blob), self.wander_deg(blob)
        if blob.velocity is None:
            # no velocity: courses fanned evenly all the way round
            speed = s.unknown_speed_mm_s
            start = np.linspace(-math.pi, math.pi, s.count, endpoint=False)
        else:
            spread = math.radians(wander) * math.sqrt(max(blob.span_s, 0.0) / 3.0)
            start = math.atan2(blob.velocity[1], blob.velocity[0]) + spread * noise[:, 0]
            speed = measured
            if cruise is not None:
                speed = np.full((s.count, 1, 1), max(measured, cruise))
                speed[0] = measured  # course 0: the measured course
                start = np.where(self._turned(blob), self._turn_heading, start)
        drift = math.radians(wander) * math.sqrt(s.step_s) * noise[:, 1:steps]
        heading = start[:, None] + np.concatenate((np.zeros((s.count, 1)), np.cumsum(drift, axis=1)), axis=1)
        step = speed * s.step_s * np.stack((np.cos(heading), np.sin(heading)), axis=-1)  # (count, steps, 2)
        grid = blob.centre + np.concatenate((np.zeros((s.count, 1, 2)), np.cumsum(step, axis=1)), axis=1)
        index = np.minimum((times // s.step_s).astype(int), steps - 1)
        within = (times - index * s.step_s)[None, :, None] / s.step_s
        return grid[:, index] + within * step[:, index], heading[:, index]


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
