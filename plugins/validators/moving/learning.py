"""What the trial's own scans say about each mover: its cruising speed and how much it wanders.

:func:`~.tracking.find_movers` measures a mover's velocity from two scans: a chord, the straight
line between where it was and where it is. One chord says little about a mover the rule was not
told about -- a wandering mover's chord is shorter than the path it drove, a stop-and-go mover's
shorter still. :func:`learn_movers` follows each mover seen now back through the trial's earlier
scans (``ValidationContext.history``), pair of scans by pair of scans, as far as it can be
followed (:class:`Track`), and gives it:

* a **cruising speed**: the largest of (its chords' speeds; its latest chord's speed over the
  chord share a mover of its wander reaches, :func:`~.tracking.chord_share`), at most
  ``max_speed_mm_s`` -- a mover faster than anything assumed is seen as fast as its chords say;
* a **wander**: the random walk of its heading, from how the headings of consecutive chords
  differ (the chord of a span points along the span's mean heading, and two adjacent spans'
  means differ by a variance of ``wander**2 * (span_1 + span_2) / 3``), pooled with the
  ``prior_wander_deg`` weighted as ``prior_weight_s`` seconds of evidence: with one chord the
  prior alone, with many the mover's own.

A chord shorter than ``still_mm`` is a stop: it says nothing of the heading, and the heading after
it is taken as unknown (:mod:`.futures` fans the courses of a mover slower than its cruising speed
all the way round). Nothing here is told how the movers behave; the two priors are the only
assumptions, and evidence overrides them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .tracking import Blob, chord_share

#: A mover's earlier position is linked to a disc of the earlier pair when they are this close (mm)
#: beyond the two discs' radii.
LINK_SLACK_MM = 150.0


@dataclass(frozen=True)
class LearningSettings:
    prior_wander_deg: float = 45.0
    prior_weight_s: float = 4.0
    max_speed_mm_s: float = 1000.0
    still_mm: float = 100.0


@dataclass(frozen=True)
class Track:
    """A mover's chords, newest first: speed (mm/s), heading (radians) and span (s) of each."""

    speeds: tuple[float, ...]
    headings: tuple[float, ...]
    spans: tuple[float, ...]

    def moving(self, index: int, still_mm: float) -> bool:
        return self.speeds[index] * self.spans[index] >= still_mm

    def wander_deg(self, s: LearningSettings) -> float:
        """The heading's random walk (degrees per square-root second): evidence pooled with the prior."""
        evidence = weight = 0.0
        for i in range(len(self.speeds) - 1):
            if self.moving(i, s.still_mm) and self.moving(i + 1, s.still_mm):
                turned = (self.headings[i] - self.headings[i + 1] + math.pi) % (2 * math.pi) - math.pi
                evidence += turned ** 2
                weight += (self.spans[i] + self.spans[i + 1]) / 3.0
        prior = math.radians(s.prior_wander_deg) ** 2 * s.prior_weight_s
        return math.degrees(math.sqrt((evidence + prior) / (weight + s.prior_weight_s)))

    def cruise_mm_s(self, wander_deg: float, s: LearningSettings) -> float:
        """The mover's cruising speed: its fastest chord, or its latest chord over the share of the
        path a mover of ``wander_deg`` keeps as chord, whichever is larger (at most the top speed)."""
        latest = self.speeds[0] / max(chord_share(wander_deg, self.spans[0]), 1e-6) if self.moving(0, s.still_mm) \
            else 0.0
        return float(min(s.max_speed_mm_s, max(max(self.speeds), latest)))


def _velocity(blob: Blob) -> np.ndarray:
    """``blob``'s measured velocity: every mover followed here has one (:func:`learn_movers` keeps
    the others as they are, :func:`_link` links only to movers with one)."""
    velocity = blob.velocity
    assert velocity is not None  # a mover of unknown velocity is never followed
    return velocity


def _departed(blob: Blob) -> np.ndarray:
    return blob.centre - _velocity(blob) * blob.span_s


def _link(blob: Blob, pair: list[Blob]) -> Blob | None:
    """The mover of ``pair`` (at the later scan of its pair) where ``blob`` was at the start of its chord."""
    where = _departed(blob)
    near = [b for b in pair if b.velocity is not None
            and math.hypot(*(b.centre - where)) <= b.radius_mm + blob.radius_mm + LINK_SLACK_MM]
    return min(near, key=lambda b: math.hypot(*(b.centre - where))) if near else None


def follow(now: Blob, earlier: list[list[Blob]], spans_s: list[float] | None = None) -> Track:
    """``now``'s chords back through ``earlier`` (the movers of each earlier pair of scans, newest
    pair first, each at the later scan of its pair), as long as each earlier position links. A
    mover that stood still over a pair is no mover of that pair: when nothing links there, the
    pair before it may link (a stop: a chord of 0 over that pair's span, ``spans_s``)."""
    velocity = _velocity(now)
    speeds, headings, spans = [float(np.hypot(*velocity))], [float(math.atan2(velocity[1], velocity[0]))], \
        [float(now.span_s)]
    blob, index = now, 0
    while index < len(earlier):
        found = _link(blob, earlier[index])
        if found is None and index + 1 < len(earlier) and spans_s is not None:
            found = _link(blob, earlier[index + 1])
            if found is not None:  # stood still over pair `index`
                speeds.append(0.0)
                headings.append(headings[-1])
                spans.append(spans_s[index])
                index += 1
        if found is None:
            break
        blob = found
        velocity = _velocity(blob)
        speeds.append(float(np.hypot(*velocity)))
        headings.append(float(math.atan2(velocity[1], velocity[0])))
        spans.append(float(blob.span_s))
        index += 1
    return Track(tuple(speeds), tuple(headings), tuple(spans))


def learn_movers(now: list[Blob], earlier: list[list[Blob]], settings: LearningSettings,
                 spans_s: list[float] | None = None) -> list[Blob]:
    """``now`` with each mover's learned cruising speed and wander (a mover of unknown velocity,
    seen once, keeps none: :mod:`.futures` fans it at the unknown speed). ``spans_s``: the time
    each earlier pair of scans spans (for a mover that stood still over one)."""
    learned = []
    for blob in now:
        if blob.velocity is None:
            learned.append(blob)
            continue
        track = follow(blob, earlier, spans_s)
        wander = track.wander_deg(settings)
        learned.append(replace(blob, wander_deg=wander, cruise_mm_s=track.cruise_mm_s(wander, settings),
                               chords=len(track.speeds)))
    return learned
