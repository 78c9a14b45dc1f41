"""When does a body moving at a held velocity first touch each of a set of points? Exactly.

A :class:`Motion` is a held velocity in the frame the body starts in (x forward, y left):
``vx_mm_s``, ``vy_mm_s`` (sideways, for a holonomic base) and a turn rate ``w_rad_s``
(counter-clockwise), for ``duration_s``. With a turn rate the body moves along an arc about the
instantaneous centre of rotation c = (-vy / w, vx / w); without one along a straight line; with no
speed it turns in place (c = 0).

Seen from the body, a still point p does the opposite: it moves along the straight p - v t, or
turns about c by -w t, on a circle of radius |p - c|. So the first time p touches the body grown
by its margin (:class:`~safeembodai_core.geometry.footprint.Body`) is the first time that line or
circle crosses one of the body's boundary pieces -- a segment or a circle -- found in closed form
(a quadratic per piece), with no time step: :func:`contact_times`. A point that starts inside the
body touches it at 0. This is the region the body sweeps, exactly, for discs and simple polygons,
for straights, arcs and turns in place.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .footprint import Body, _cross

_TWO_PI = 2.0 * math.pi
#: a turn that moves no point of the swept region by more than this (mm) is driven as a straight: its
#: centre of rotation would lie so far away that the arc's arithmetic loses more than it gains
_STRAIGHT_ENOUGH_MM = 1e-2


@dataclass(frozen=True)
class Motion:
    """A velocity held for ``duration_s`` seconds, in the frame the body starts in (module docstring)."""

    vx_mm_s: float
    vy_mm_s: float
    w_rad_s: float
    duration_s: float

    def __post_init__(self) -> None:
        for name in ("vx_mm_s", "vy_mm_s", "w_rad_s", "duration_s"):
            value = float(getattr(self, name))
            if not math.isfinite(value):
                raise ValueError(f"Motion.{name} must be finite, got {value!r}")
            object.__setattr__(self, name, value)
        if self.duration_s < 0:
            raise ValueError(f"Motion.duration_s must be >= 0, got {self.duration_s!r}")

    @property
    def speed_mm_s(self) -> float:
        return math.hypot(self.vx_mm_s, self.vy_mm_s)

    def straight_enough(self, extent_mm: float) -> bool:
        """True when driving this as a straight moves no point within ``extent_mm`` of the path by more
        than ``_STRAIGHT_ENOUGH_MM`` (the turn is that small): the one test every computation uses."""
        return (self.centre_travel_mm + extent_mm) * abs(self.w_rad_s) * self.duration_s <= _STRAIGHT_ENOUGH_MM

    @property
    def centre_travel_mm(self) -> float:
        """How far the robot's centre travels along its path (an arc is no longer than this)."""
        return self.speed_mm_s * self.duration_s

    def pose_at(self, t: float) -> tuple[float, float, float]:
        """The body's pose ``(x_mm, y_mm, heading_rad)`` after ``t`` seconds, in the start frame.

        Written as v * sin(wt) / w and v * 2 sin(wt/2)^2 / w, which stay exact as w goes to 0 (the
        centre-of-rotation form c - R(wt) c cancels catastrophically there)."""
        w, wt = self.w_rad_s, self.w_rad_s * t
        if w == 0.0:
            along, across = t, 0.0
        else:
            along, across = math.sin(wt) / w, 2.0 * math.sin(wt / 2.0) ** 2 / w
        vx, vy = self.vx_mm_s, self.vy_mm_s
        return vx * along - vy * across, vx * across + vy * along, wt

    def scaled(self, factor: float) -> "Motion":
        """The same path driven ``factor`` times as fast, for the same duration."""
        return Motion(self.vx_mm_s * factor, self.vy_mm_s * factor, self.w_rad_s * factor, self.duration_s)


def contact_times(points: np.ndarray, motion: Motion, body: Body) -> np.ndarray:
    """Per (N, 2) point (mm, start frame): the first time in [0, ``motion.duration_s``] the moving
    ``body`` touches it; ``inf`` when it never does within the duration (module docstring)."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    times = np.full(len(points), np.inf)
    if not len(points):
        return times
    # a point within reach of where the body starts is always looked at, whatever the path's arithmetic says
    near = np.flatnonzero(near_path(points, motion, body.reach_mm)
                          | (np.hypot(points[:, 0], points[:, 1]) <= body.reach_mm))
    start = body.inside(points[near])
    times[near[start]] = 0.0
    rest = near[~start]
    if rest.size == 0 or motion.duration_s == 0.0:
        return times
    segments, circles = body.boundary()
    p = points[rest]
    if motion.straight_enough(body.reach_mm + float(np.max(np.abs(p)))):
        found = _line_contacts(p, np.array([motion.vx_mm_s, motion.vy_mm_s]), segments, circles)
    else:
        found = _arc_contacts(p, motion, segments, circles)
    times[rest] = np.where(found <= motion.duration_s, found, np.inf)
    return times


def near_path(points: np.ndarray, motion: Motion, reach_mm: float) -> np.ndarray:
    """Per point: whether it lies within ``reach_mm`` of the path the body's centre drives (only
    such a point can be touched by a body that reaches no farther than that from its centre). A
    distance that cannot be computed (NaN) keeps the point: the filter only ever drops."""
    w, travel = motion.w_rad_s, motion.centre_travel_mm
    if travel <= 1e-9:  # the centre stays put (to a nanometre): a turn in place, or no motion
        return ~(np.hypot(points[:, 0], points[:, 1]) > reach_mm + travel)
    turned = w * motion.duration_s
    if motion.straight_enough(0.0):  # the centre's path is its chord, to within _STRAIGHT_ENOUGH_MM
        end = np.array(motion.pose_at(motion.duration_s)[:2])
        length2 = float(end @ end)
        if not 0.0 < length2 < math.inf:
            return ~(np.hypot(points[:, 0], points[:, 1]) > reach_mm + travel)
        t = np.clip(points @ end / length2, 0.0, 1.0)
        return ~(np.hypot(*(points - t[:, None] * end).T) > reach_mm + _STRAIGHT_ENOUGH_MM)
    centre = np.array([-motion.vy_mm_s / w, motion.vx_mm_s / w])
    radius = math.hypot(*centre)
    rel = points - centre
    if abs(turned) >= _TWO_PI:
        return np.abs(np.hypot(rel[:, 0], rel[:, 1]) - radius) <= reach_mm
    start = math.atan2(-centre[1], -centre[0])  # the robot's centre, seen from the centre of rotation, at t = 0
    along = np.mod((np.arctan2(rel[:, 1], rel[:, 0]) - start) * math.copysign(1.0, turned), _TWO_PI)
    on_arc = along <= abs(turned)
    to_circle = np.abs(np.hypot(rel[:, 0], rel[:, 1]) - radius)
    end = np.array(motion.pose_at(motion.duration_s)[:2])
    to_ends = np.minimum(np.hypot(points[:, 0], points[:, 1]), np.hypot(*(points - end).T))
    return ~(np.where(on_arc, to_circle, to_ends) > reach_mm + 1e-9)


def _line_contacts(p: np.ndarray, v: np.ndarray, segments: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """First t >= 0 at which p - v t meets a segment or a circle (inf: never)."""
    best = np.full(len(p), np.inf)
    if float(v @ v) == 0.0:  # no speed (or too little to square): the point never moves
        return best
    if len(segments):
        a, e = segments[None, :, 0, :], segments[None, :, 1, :] - segments[None, :, 0, :]
        r = p[:, None, :] - a
        det = _cross(v[None, None, :], e)
        ok = np.abs(det) > 1e-12
        safe = np.where(ok, det, 1.0)
        t, s = _cross(r, e) / safe, _cross(v[None, None, :], r) / safe
        hit = ok & (t >= 0.0) & (s >= -1e-12) & (s <= 1.0 + 1e-12)
        best = np.minimum(best, np.min(np.where(hit, t, np.inf), axis=1))
    if len(circles):
        r = p[:, None, :] - circles[None, :, :2]
        vv, vr = float(v @ v), r @ v
        disc = vr * vr - vv * (np.sum(r * r, axis=2) - circles[None, :, 2] ** 2)
        t = (vr - np.sqrt(np.maximum(disc, 0.0))) / vv
        best = np.minimum(best, np.min(np.where((disc >= 0.0) & (t >= 0.0), t, np.inf), axis=1))
    return best


def _arc_contacts(p: np.ndarray, motion: Motion, segments: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """First t >= 0 at which p, turning about the centre of rotation by -w t, meets a piece."""
    w = motion.w_rad_s
    centre = np.array([-motion.vy_mm_s / w, motion.vx_mm_s / w])
    rel = p - centre
    rho2 = np.sum(rel * rel, axis=1)
    phi0 = np.arctan2(rel[:, 1], rel[:, 0])
    crossings: list[np.ndarray] = []  # (N, K) points where the point's circle meets a piece
    if len(segments):
        a = segments[:, 0, :] - centre
        e = segments[:, 1, :] - segments[:, 0, :]
        qa, qb = np.sum(e * e, axis=1), 2.0 * np.sum(e * a, axis=1)
        qc = np.sum(a * a, axis=1)[None, :] - rho2[:, None]
        disc = qb[None, :] ** 2 - 4.0 * qa[None, :] * qc
        root = np.sqrt(np.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            s = (-qb[None, :] + sign * root) / (2.0 * qa[None, :])
            x = a[None, :, :] + s[..., None] * e[None, :, :]
            valid = (disc >= 0.0) & (s >= -1e-12) & (s <= 1.0 + 1e-12)
            crossings.append(np.where(valid[..., None], x, np.nan))
    if len(circles):
        k = circles[:, :2] - centre
        d = np.hypot(k[:, 0], k[:, 1])
        usable = d > 1e-12
        d_safe = np.where(usable, d, 1.0)
        along = (rho2[:, None] - circles[None, :, 2] ** 2 + d[None, :] ** 2) / (2.0 * d_safe[None, :])
        h2 = rho2[:, None] - along ** 2
        unit = k / d_safe[:, None]
        perp = np.column_stack((-unit[:, 1], unit[:, 0]))
        h = np.sqrt(np.maximum(h2, 0.0))
        for sign in (-1.0, 1.0):
            x = along[..., None] * unit[None, :, :] + sign * h[..., None] * perp[None, :, :]
            crossings.append(np.where((usable[None, :] & (h2 >= 0.0))[..., None], x, np.nan))
    if not crossings:
        return np.full(len(p), np.inf)
    x = np.concatenate(crossings, axis=1)
    psi = np.arctan2(x[..., 1], x[..., 0])
    turned = np.mod((phi0[:, None] - psi) * math.copysign(1.0, w), _TWO_PI)  # the angle turned to get there
    t = np.where(np.isnan(psi), np.inf, turned / abs(w))
    return np.min(t, axis=1)


__all__ = ["Motion", "contact_times", "near_path"]
