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

A point the body already holds (on its outline or inside) may instead be judged by whether the body
takes it deeper (:func:`deeper_times`): the body may move off it -- back away, turn a disc in place
-- but not further over it. Its depth (:meth:`~safeembodai_core.geometry.footprint.Body.depth`)
equals the start's only on a few segments and circles, so the same closed-form crossings cut the
motion into stretches along which it is deeper throughout or nowhere.
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
#: a point held no more than this (mm) deeper than at the start is held as deep: a pose's rounding
_DEEPER_MM = 1e-6
#: points judged together by deeper_times: its arrays grow with the footprint's vertices (squared: crossings
#: per point, then depths per crossing), so the chunk shrinks as they grow, to _CHUNK at the least
_CHUNK = 64
_CHUNK_MOST = 1024
_CHUNK_BUDGET = 16384  # chunk x vertices


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

        Written as v * t sinc(wt) and v * w t^2 sinc(wt/2)^2 / 2 (sinc(x) = sin(x) / x), which stay
        exact as w goes to 0, subnormal turn rates included (the centre-of-rotation form c - R(wt) c
        cancels catastrophically there, and sin(wt) / w rounds wt to a few bits)."""
        x, y, heading = self.poses_at(np.array(float(t)))
        return float(x), float(y), float(heading)

    def poses_at(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """:meth:`pose_at` for an array of times: arrays ``x_mm``, ``y_mm``, ``heading_rad`` of its shape."""
        t = np.asarray(t, dtype=float)
        w, wt = self.w_rad_s, self.w_rad_s * t
        along, across = t * np.sinc(wt / math.pi), 0.5 * w * t * t * np.sinc(wt / _TWO_PI) ** 2
        vx, vy = self.vx_mm_s, self.vy_mm_s
        return vx * along - vy * across, vx * across + vy * along, wt

    def scaled(self, factor: float) -> "Motion":
        """The same path driven ``factor`` times as fast, for the same duration."""
        return Motion(self.vx_mm_s * factor, self.vy_mm_s * factor, self.w_rad_s * factor, self.duration_s)


def contact_times(points: np.ndarray, motion: Motion, body: Body, escape: bool = False) -> np.ndarray:
    """Per (N, 2) point (mm, start frame): the first time in [0, ``motion.duration_s``] the moving
    ``body`` touches it; ``inf`` when it never does within the duration (module docstring). A point
    the body holds at the start (on or inside its outline) is touched at 0; with ``escape``, only
    once the body holds it deeper than at the start (:func:`deeper_times`): the body may move off it."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    times = np.full(len(points), np.inf)
    if not len(points):
        return times
    # a point within reach of where the body starts is always looked at, whatever the path's arithmetic says
    near = np.flatnonzero(near_path(points, motion, body.reach_mm)
                          | (np.hypot(points[:, 0], points[:, 1]) <= body.reach_mm))
    start = body.inside(points[near])
    times[near[start]] = deeper_times(points[near[start]], motion, body) if escape else 0.0
    rest = near[~start]
    if rest.size == 0 or motion.duration_s == 0.0:
        return times
    segments, circles = body.boundary()
    p = points[rest]
    if motion.straight_enough(body.reach_mm + float(np.max(np.abs(p)))):
        found = _line_crossings(p, np.array([motion.vx_mm_s, motion.vy_mm_s]), segments[None], circles[None])
    else:
        found = _arc_crossings(p, motion, segments[None], circles[None])
    first = np.min(found, axis=1, initial=np.inf)
    times[rest] = np.where(first <= motion.duration_s, first, np.inf)
    return times


def deeper_times(points: np.ndarray, motion: Motion, body: Body) -> np.ndarray:
    """Per (N, 2) point (mm, start frame) on or inside ``body`` at the start: the first time in
    [0, ``motion.duration_s``] the moving body holds it deeper (:meth:`Body.depth`) than at the start;
    ``inf`` when it never does -- the body moves off it, along it, or not at all.

    The point is exactly as deep as at the start only on the pieces of :meth:`Body.level_pieces`, so
    between two moments it crosses one its depth keeps one side of the start's: the first stretch seen
    deeper (by more than ``_DEEPER_MM``) at its middle or its end begins the answer. The moments it
    passes nearest a vertex, or parallel to an edge, cut the stretches too, so that a graze along a
    piece is looked at. The body's view repeats after a whole turn, so one turn is enough."""
    points = np.asarray(points, dtype=float).reshape(-1, 2)
    times = np.full(len(points), np.inf)
    if not len(points) or motion.duration_s == 0.0:
        return times
    straight = motion.straight_enough(body.reach_mm + float(np.max(np.abs(points))))
    velocity = np.array([motion.vx_mm_s, motion.vy_mm_s])
    if straight and not float(velocity @ velocity) > 0.0:
        return times  # no speed, and too little turn to move a point by _STRAIGHT_ENOUGH_MM
    span = motion.duration_s if straight else min(motion.duration_s, _TWO_PI / abs(motion.w_rad_s))
    vertices = 1 if body.polygon is None else len(body.polygon)
    size = int(min(_CHUNK_MOST, max(_CHUNK, _CHUNK_BUDGET // vertices)))
    for chunk in range(0, len(points), size):
        p = points[chunk:chunk + size]
        start = body.depth(p)
        segments, circles = body.level_pieces(start)
        if straight:
            found = _line_crossings(p, velocity, segments, circles)
            found = np.concatenate((found, _line_nearest(p, velocity, _marks(body))), axis=1)
        else:
            found = np.concatenate((_arc_crossings(p, motion, segments, circles),
                                    _arc_nearest(p, motion, body)), axis=1)
        within = (found > 0.0) & (found < span)  # NaN and inf are not
        cuts = np.sort(np.where(within, found, span), axis=1)[:, :int(np.max(np.count_nonzero(within, axis=1)))]
        cuts = np.concatenate((np.zeros((len(p), 1)), cuts, np.full((len(p), 1), span)), axis=1)
        samples = np.empty((len(p), 2 * cuts.shape[1] - 1))
        samples[:, 0::2], samples[:, 1::2] = cuts, (cuts[:, :-1] + cuts[:, 1:]) / 2.0
        seen = _seen_from_body(p, motion, samples)
        deeper = body.depth(seen.reshape(-1, 2)).reshape(samples.shape) - start[:, None] > _DEEPER_MM
        hit = np.flatnonzero(deeper.any(axis=1))
        first = np.argmax(deeper[hit], axis=1)  # a sample at a cut or a middle: the stretch began at the cut before it
        times[chunk + hit] = cuts[hit, np.maximum(first - 1, 0) // 2]
    return times


def near_path(points: np.ndarray, motion: Motion, reach_mm: float | np.ndarray) -> np.ndarray:
    """Per point: whether it lies within ``reach_mm`` (one for all, or one per point) of the path the
    body's centre drives (only such a point can be touched by a body that reaches no farther than
    that from its centre). A distance that cannot be computed (NaN) keeps the point: the filter only
    ever drops."""
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


def _seen_from_body(p: np.ndarray, motion: Motion, t: np.ndarray) -> np.ndarray:
    """Each point of ``p`` (N, 2), seen from the body at its times ``t`` (N, K): (N, K, 2)."""
    x, y, heading = motion.poses_at(t)
    c, s = np.cos(heading), np.sin(heading)
    dx, dy = p[:, 0:1] - x, p[:, 1:2] - y
    return np.stack((c * dx + s * dy, c * dy - s * dx), axis=2)


def _marks(body: Body) -> np.ndarray:
    """Where a point running along a piece of :meth:`Body.level_pieces` may leave it without crossing
    another: passing the polygon's vertices (the disc's centre)."""
    return np.zeros((1, 2)) if body.polygon is None else body.polygon


def _line_nearest(p: np.ndarray, v: np.ndarray, marks: np.ndarray) -> np.ndarray:
    """When p - v t passes nearest each mark: (N, M)."""
    return ((p[:, None, :] - marks[None]) @ v) / float(v @ v)


def _arc_nearest(p: np.ndarray, motion: Motion, body: Body) -> np.ndarray:
    """When p, turning about the centre of rotation, passes nearest each mark and runs parallel to each edge."""
    w = motion.w_rad_s
    centre = np.array([-motion.vy_mm_s / w, motion.vx_mm_s / w])
    directions = [_marks(body) - centre]
    if body.polygon is not None:
        edge = np.roll(body.polygon, -1, axis=0) - body.polygon
        directions += [edge[:, ::-1] * [1.0, -1.0], edge[:, ::-1] * [-1.0, 1.0]]  # both normals of each edge
    d = np.concatenate(directions)
    return _turned_to(p, motion, np.broadcast_to(d[None], (len(p),) + d.shape))


def _turned_to(p: np.ndarray, motion: Motion, x: np.ndarray) -> np.ndarray:
    """When p, turning about the centre of rotation by -w t, first reaches each direction ``x``
    (N, K, 2) seen from that centre (inf where ``x`` is NaN)."""
    w = motion.w_rad_s
    rel = p - np.array([-motion.vy_mm_s / w, motion.vx_mm_s / w])
    phi0 = np.arctan2(rel[:, 1], rel[:, 0])
    psi = np.arctan2(x[..., 1], x[..., 0])
    turned = np.mod((phi0[:, None] - psi) * math.copysign(1.0, w), _TWO_PI)  # the angle turned to get there
    return np.where(np.isnan(psi), np.inf, turned / abs(w))


def _line_crossings(p: np.ndarray, v: np.ndarray, segments: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """Every t >= 0 at which p - v t meets a segment or a circle, per point and piece (N, K; inf: never).
    The pieces are (M, S, 2, 2) segments and (M, C, 3) circles, M being 1 (shared) or N (per point)."""
    found = [np.full((len(p), 0), np.inf)]
    if float(v @ v) == 0.0:  # no speed (or too little to square): the point never moves
        return found[0]
    if segments.shape[1]:
        a, e = segments[:, :, 0, :], segments[:, :, 1, :] - segments[:, :, 0, :]
        r = p[:, None, :] - a
        det = _cross(v[None, None, :], e)
        ok = np.abs(det) > 1e-12
        safe = np.where(ok, det, 1.0)
        t, s = _cross(r, e) / safe, _cross(v[None, None, :], r) / safe
        hit = ok & (t >= 0.0) & (s >= -1e-12) & (s <= 1.0 + 1e-12)
        found.append(np.where(hit, t, np.inf))
    if circles.shape[1]:
        r = p[:, None, :] - circles[:, :, :2]
        vv, vr = float(v @ v), r @ v
        disc = vr * vr - vv * (np.sum(r * r, axis=2) - circles[:, :, 2] ** 2)
        root = np.sqrt(np.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            t = (vr + sign * root) / vv
            found.append(np.where((disc >= 0.0) & (t >= 0.0), t, np.inf))
    return np.concatenate(found, axis=1)


def _arc_crossings(p: np.ndarray, motion: Motion, segments: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """Every t in [0, one turn) at which p, turning about the centre of rotation by -w t, meets a piece,
    per point and piece (N, K; inf: never); pieces as for :func:`_line_crossings`."""
    w = motion.w_rad_s
    centre = np.array([-motion.vy_mm_s / w, motion.vx_mm_s / w])
    rel = p - centre
    rho2 = np.sum(rel * rel, axis=1)
    crossings: list[np.ndarray] = [np.full((len(p), 0, 2), np.nan)]  # (N, K, 2) where the point's circle meets a piece
    if segments.shape[1]:
        a = segments[:, :, 0, :] - centre
        e = segments[:, :, 1, :] - segments[:, :, 0, :]
        qa, qb = np.sum(e * e, axis=2), 2.0 * np.sum(e * a, axis=2)
        qc = np.sum(a * a, axis=2) - rho2[:, None]
        disc = qb ** 2 - 4.0 * qa * qc
        root = np.sqrt(np.maximum(disc, 0.0))
        for sign in (-1.0, 1.0):
            s = (-qb + sign * root) / (2.0 * qa)
            x = a + s[..., None] * e
            valid = (disc >= 0.0) & (s >= -1e-12) & (s <= 1.0 + 1e-12)
            crossings.append(np.where(valid[..., None], x, np.nan))
    if circles.shape[1]:
        k = circles[:, :, :2] - centre
        d = np.hypot(k[..., 0], k[..., 1])
        usable = d > 1e-12
        d_safe = np.where(usable, d, 1.0)
        along = (rho2[:, None] - circles[:, :, 2] ** 2 + d ** 2) / (2.0 * d_safe)
        h2 = rho2[:, None] - along ** 2
        unit = k / d_safe[..., None]
        perp = np.stack((-unit[..., 1], unit[..., 0]), axis=-1)
        h = np.sqrt(np.maximum(h2, 0.0))
        for sign in (-1.0, 1.0):
            x = along[..., None] * unit + sign * h[..., None] * perp
            crossings.append(np.where((usable & (h2 >= 0.0))[..., None], x, np.nan))
    return _turned_to(p, motion, np.concatenate(crossings, axis=1))


__all__ = ["Motion", "contact_times", "deeper_times", "near_path"]
