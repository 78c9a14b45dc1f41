"""``swept_body``: the region the robot's body sweeps must hold no return and no unseen space.

The body is the robot's disc, or its polygon footprint (``RobotSpec.footprint_mm``), grown by
``margin_mm``. A ``straight``, a ``turn`` in place, or a held velocity (an arc, a straight, a turn,
or a holonomic drift) moves it; :func:`~safeembodai_core.geometry.contact_times` gives, exactly,
when it first touches each point (:mod:`safeembodai_core.geometry.sweep`). The motion is refused
when it touches

* ``min_points`` returns of the scan (1 by default: any return; Nav2's collision monitor counts
  ``min_points`` too), or
* one sample of space the scan cannot vouch for: along a beam with no reading (``nan``: no reading,
  below ``range_min``, outside the field of view), behind a return where the next beam saw farther
  (the edge of its shadow), and past the sensor's range. A free beam (``inf``) is free only out to
  the range. Samples inside the body where the scan was taken are dropped: the robot stood there.
  From a scanner off the centre (:class:`~safeembodai_core.ros.laser_scan.MountedScan`) these are
  derived from its own view, from where it stood: along its beams, not along the bins round the
  centre, whose rays do not follow the beams (at a shadow's edge a bin with no beam is unseen at every
  range, though the scanner saw into it; another holds free a ray that crosses a shadow). A scanner
  at the centre is its own view: judged as it always was.

A return the body already holds -- on its outline (Nav2 counts it outside) or inside -- counts only
once the motion takes the body deeper over it (:func:`~safeembodai_core.geometry.sweep.deeper_times`):
a robot in contact may back off it, into space the scan saw.

Only points within reach of the motion are looked at: the centre's travel plus the body's reach.
The work does not grow with the speed asked: unseen space is looked for out to
:data:`FIRST_LOOK_MM` along the path first, farther only while no touch is found before the body
could reach what is not yet looked at, and of a long ray only the stretches that come near the path
are sampled -- the same samples, so the same verdicts, as looking everywhere within reach.
A refusal says what was touched, where, and how much of the motion is safe ("at most N mm is
safe", "at most N deg"). Beyond the paper: V(C) judges the beams within ±r of the heading only, so
it drives through a return just off the heading that the body sweeps, and accepts any turn.
"""

from __future__ import annotations

import math
from typing import Callable, Literal

import numpy as np

from safeembodai_core.geometry import Motion, contact_times
from safeembodai_core.geometry.sweep import near_path
from safeembodai_core.guard.held_motion import MotionValidator, MotionVerdict
from safeembodai_core.models import Advice, ControlSignal, LidarScan, Straight, Verdict
from safeembodai_core.ros.laser_scan import MountedScan
from safeembodai_core.validation.context import ValidationContext

from .rules import checked_scan

_UNSEEN = ("no reading", "behind a return", "beyond the sensor's range")
_DEEPER = "goes deeper over a return of the scan"
_JUMP_STEPS = 2.0  # a neighbour this many sample steps farther leaves a shadow edge worth sampling
#: The farthest a judged motion's centre may travel (100 km); beyond it nothing is placed, so it is refused.
MAX_TRAVEL_MM = 1e8
#: Unseen space is first looked for this far (mm) along the path past the body; each next look is four times as far.
FIRST_LOOK_MM = 2000.0
_CULL_ABOVE = 20_000  # of more samples along rays than this, stretches of ray far from the path are dropped first
_FINEST = 8  # samples in the shortest stretch of ray judged near the path or not
#: (points, slack mm) -> per point: whether it may lie within the slack of a point near the judged path
Near = Callable[[np.ndarray, np.ndarray], np.ndarray]


def _stretches(starts: np.ndarray, counts: np.ndarray, angles: np.ndarray, step: float,
               near: Near) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The stretches of ray that may hold a sample near the path, as (ray, first sample, samples),
    in the rays' order and outwards. A stretch whose middle lies farther from the path than the
    stretch is long (``near`` with that slack says no) holds no sample near it and is dropped; the
    others are halved until :data:`_FINEST` samples long."""
    ray = np.flatnonzero(counts > 0)
    first, n = np.zeros(len(ray), dtype=int), counts[ray]
    done = []
    while ray.size:
        half = step * (n - 1) / 2.0
        middle = starts[ray] + step * first + half
        ok = near(np.column_stack((middle * np.cos(angles[ray]), middle * np.sin(angles[ray]))), half)
        ray, first, n = ray[ok], first[ok], n[ok]
        fine = n <= _FINEST
        done.append((ray[fine], first[fine], n[fine]))
        ray, first, n = ray[~fine], first[~fine], n[~fine]
        low = n // 2
        ray, first, n = np.concatenate((ray, ray)), np.concatenate((first, first + low)), np.concatenate((low, n - low))
    ray, first, n = (np.concatenate(parts) for parts in zip(*done))
    order = np.lexsort((first, ray))
    return ray[order], first[order], n[order]


def _rays(angles: np.ndarray, starts: np.ndarray, stops: np.ndarray, step: float,
          thin_rad: float | None = None, near: Near | None = None) -> np.ndarray:
    """Samples every ``step`` mm along each beam from ``starts`` to ``stops`` (scan frame). With
    ``thin_rad`` (the beams' spacing, for neighbouring beams that are all unread) a ring of radius r
    keeps only every k-th beam, k = step / (r * thin_rad): samples about ``step`` apart across too.
    With ``near``, of many samples only those of the stretches of ray that may come near the path
    (:func:`_stretches`): the same samples, in the same order, less some that lie far from it."""
    counts = np.maximum(np.floor((stops - starts) / step).astype(int) + 1, 0)
    total = int(counts.sum())
    if not total:
        return np.empty((0, 2))
    if near is not None and total > _CULL_ABOVE:
        ray, first, n = _stretches(starts, counts, angles, step, near)
    else:
        ray, first, n = np.arange(len(angles)), np.zeros(len(angles), dtype=int), counts
    beam = np.repeat(ray, n)
    radii = starts[beam] + step * (np.repeat(first, n) + np.arange(beam.size) - np.repeat(np.cumsum(n) - n, n))
    if thin_rad is not None:
        every = np.maximum(1, np.floor(step / np.maximum(radii * thin_rad, 1e-9))).astype(int)
        index = np.rint(angles[beam] / thin_rad).astype(int)
        keep = index % every == 0
        beam, radii = beam[keep], radii[keep]
    return np.column_stack((radii * np.cos(angles[beam]), radii * np.sin(angles[beam])))


def scene_returns(scan: LidarScan, reach_mm: float) -> np.ndarray:
    """The returns of the binned scan within ``reach_mm`` of its origin (the frame it was taken in)."""
    ranges = scan.ranges_mm
    angles = np.radians(scan.angles_deg)
    near = np.isfinite(ranges) & (ranges <= reach_mm)
    return np.column_stack((ranges[near] * np.cos(angles[near]), ranges[near] * np.sin(angles[near])))


def unseen_samples(scan: LidarScan, reach_mm: float, step_mm: float,
                   near: Near | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The unseen samples within ``reach_mm`` of the scan's origin, with their kind (an index into
    ``_UNSEEN``), in the frame the scan was taken in (module docstring); samples inside the body
    where the scan was taken are still among them. Every sample lies where it would for a larger
    ``reach_mm``, and in the same order: a smaller reach keeps those within it. ``near`` (points,
    slack) -> mask may drop stretches of ray whose samples all lie far from the path (:func:`_rays`)."""
    ranges = scan.ranges_mm
    angles = np.radians(scan.angles_deg)
    read = ~np.isnan(ranges)
    depth = np.where(read, np.minimum(ranges, scan.max_range_mm), np.nan)
    parts, kinds = [], []
    unread = ~read
    if unread.any():
        stop = min(scan.max_range_mm, reach_mm)
        # every beam's ray where its neighbours are unread too (the inside of an unread wedge is
        # sampled about step_mm apart across); a wedge's edge rays in full
        inner = unread & np.roll(unread, 1) & np.roll(unread, -1)
        edges = unread & ~inner
        parts.append(np.concatenate([
            _rays(angles[inner], np.zeros(int(inner.sum())), np.full(int(inner.sum()), stop), step_mm,
                  math.radians(scan.increment_deg), near),
            _rays(angles[edges], np.zeros(int(edges.sum())), np.full(int(edges.sum()), stop), step_mm, near=near)]))
        kinds.append(0)
    for neighbour in (np.roll(depth, -1), np.roll(depth, 1)):
        edge = read & ~np.isnan(neighbour) & (neighbour > depth + _JUMP_STEPS * step_mm) & (depth < reach_mm)
        if edge.any():
            parts.append(_rays(angles[edge], depth[edge] + step_mm, np.minimum(neighbour[edge], reach_mm), step_mm,
                               near=near))
            kinds.append(1)
    if reach_mm >= scan.max_range_mm:  # the body can leave the disc the sensor saw: its rim where beams saw free
        rim = np.arange(0.0, 2 * math.pi, step_mm / scan.max_range_mm)
        beam = np.rint(np.degrees(rim) / scan.increment_deg).astype(int) % scan.beam_count
        rim = rim[read[beam] & (depth[beam] >= scan.max_range_mm)]
        parts.append(scan.max_range_mm * np.column_stack((np.cos(rim), np.sin(rim))))
        kinds.append(2)
    if not parts:
        return np.empty((0, 2)), np.empty(0, dtype=int)
    labels = np.concatenate([np.full(len(p), k) for p, k in zip(parts, kinds)])
    return np.concatenate(parts), labels


def scanner_view(scan: LidarScan) -> tuple[LidarScan, tuple[float, float] | None]:
    """The scan unseen space is derived from, and where it was taken (mm, robot frame): a mounted
    scanner's own view from its mount (:class:`~safeembodai_core.ros.laser_scan.MountedScan`: what
    its beams saw free, not rebinned round the centre), else the scan itself, from the centre (None)."""
    if isinstance(scan, MountedScan) and scan.view is not None:
        return scan.view, scan.origin_mm
    return scan, None


def _where(point: np.ndarray) -> str:
    x, y = float(point[0]), float(point[1])
    side = "on the centre line" if abs(y) < 0.5 else f"and {abs(y):.0f} mm {'left' if y > 0 else 'right'}"
    return f"{abs(x):.0f} mm {'ahead' if x >= 0 else 'behind'} {side}"


class SweptBodyRule(MotionValidator):
    """Refuses a motion whose swept body (plus margin) touches a return or space the scan did not see."""

    name = "swept_body"

    def __init__(self, options) -> None:
        self.options = options

    def _contacts(self, motion: Motion, context: ValidationContext) -> list[tuple[float, str, np.ndarray] | None]:
        """The first touch of ``min_points`` returns, and of unseen space, each as (time, what, point) or None."""
        o = self.options
        scan = checked_scan(context, self.name, o.expected_beams)
        body = context.robot.body(o.margin_mm)
        x, y, _ = context.offset
        here = np.zeros(2)
        if not motion.centre_travel_mm <= MAX_TRAVEL_MM:  # NaN too: a motion this rule cannot place
            return [None, (0.0, f"touches nothing it can judge: the motion covers {motion.centre_travel_mm:.3g} mm, "
                                f"more than {MAX_TRAVEL_MM:.0f}", here)]
        view, origin = scanner_view(scan)
        ox, oy = (0.0, 0.0) if origin is None else origin
        if math.hypot(x - ox, y - oy) + body.reach_mm >= view.max_range_mm:
            return [None, (0.0, f"touches space the scan did not see (the body reaches past the sensor's range of "
                                f"{view.max_range_mm:g} mm)", here)]
        reach = math.hypot(x, y) + motion.centre_travel_mm + body.reach_mm + o.unseen_step_mm
        returns = scene_returns(scan, reach)
        if scan.returns_mm is not None and len(scan.returns_mm):  # the unbinned returns as well
            exact = scan.returns_mm[~(np.hypot(scan.returns_mm[:, 0], scan.returns_mm[:, 1]) > reach)]
            returns = np.concatenate((returns, exact))
        touched = None
        if len(returns):
            planned = context.to_planned_frame(returns)
            times = contact_times(planned, motion, body, escape=True)
            if np.count_nonzero(np.isfinite(times)) >= o.min_points:
                order = np.argsort(times, kind="stable")
                held = bool(body.inside(planned[order[:1]])[0])
                what = _DEEPER if held else "touches a return of the scan"
                touched = (float(times[order[o.min_points - 1]]), what, planned[order[0]])
        return [touched, self._first_unseen(view, origin, motion, context)]

    def _first_unseen(self, scan: LidarScan, origin: tuple[float, float] | None, motion: Motion,
                      context: ValidationContext) -> tuple[float, str, np.ndarray] | None:
        """The first touch of unseen space within reach of the motion, as (time, what, point) or None:
        derived from ``scan`` taken at ``origin`` (the scanner's own view, :func:`scanner_view`; None:
        at the robot's centre). Looked for out to :data:`FIRST_LOOK_MM` along the path first, then four
        times as far each time, until a touch is found before the body could reach the samples not
        yet looked at (the centre moves ``speed * t`` by time ``t``): the work grows with how far
        the first touch is, not with how far the motion goes. Of many samples, only those on
        stretches of ray near the path are made (:func:`_stretches`)."""
        o = self.options
        body = context.robot.body(o.margin_mm)
        x, y, _ = context.offset
        ox, oy = (0.0, 0.0) if origin is None else origin
        far = math.hypot(x - ox, y - oy) + motion.centre_travel_mm  # the farthest the centre gets from the origin
        shift = None if origin is None else np.array(origin, dtype=float)
        if shift is not None and motion.straight_enough(0.0):  # along a straight, from a scanner ahead: its far end
            seen_from = context.to_planned_frame(shift[None])[0]
            end = np.array(motion.pose_at(motion.duration_s)[:2])
            far = min(far, max(float(np.hypot(*seen_from)), float(np.hypot(*(end - seen_from)))) + 1.0)
        reach = far + body.reach_mm + o.unseen_step_mm
        start = math.hypot(x - ox, y - oy) + body.reach_mm  # no point of the body lies farther from the origin at t = 0

        def into_scan(points: np.ndarray) -> np.ndarray:  # from the origin's frame into the scan's (the robot's)
            return points if shift is None else points + shift

        def near(points: np.ndarray, slack: np.ndarray) -> np.ndarray:  # 1 mm more: the frame change's rounding
            return near_path(context.to_planned_frame(into_scan(points)), motion, body.reach_mm + slack + 1.0)

        look = FIRST_LOOK_MM
        while True:
            radius = min(reach, start + o.unseen_step_mm + look)
            unseen, labels = unseen_samples(scan, radius, o.unseen_step_mm, near)
            unseen = into_scan(unseen)
            hidden = None
            if len(unseen):
                planned = context.to_planned_frame(unseen)
                keep = np.flatnonzero(near_path(planned, motion, body.reach_mm))
                if keep.size:
                    keep = keep[~body.inside(unseen[keep])]  # where the robot stood when it scanned
                if keep.size:
                    times = contact_times(planned[keep], motion, body)
                    k = int(np.argmin(times))
                    if np.isfinite(times[k]):
                        what = f"touches space the scan did not see ({_UNSEEN[labels[keep[k]]]})"
                        hidden = (float(times[k]), what, planned[keep[k]])
            # a sample not looked at lies beyond radius: the body cannot touch it before it has come that far
            if radius >= reach or (hidden is not None
                                   and start + hidden[0] * motion.speed_mm_s + 1.0 < radius * (1.0 - 1e-9)):
                return hidden
            look *= 4.0

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        if isinstance(signal, Straight):
            motion = Motion(math.copysign(1.0, signal.signed_distance_mm), 0.0, 0.0, signal.distance)
        else:
            motion = Motion(0.0, 0.0, math.copysign(1.0, signal.signed_angle_deg), math.radians(signal.angle))
        hits = [c for c in self._contacts(motion, context) if c is not None]
        if not hits:
            return Verdict(rule=self.name, valid=True)
        along, what, point = min(hits, key=lambda c: c[0])
        body = context.robot.body(self.options.margin_mm).describe()
        if isinstance(signal, Straight):
            safe = math.ceil(along) - 1  # strictly short of the touch: following the advice must pass
            direction = signal.direction
            away = "move off it first" if what == _DEEPER else "turn away first"
            advice = (f"going {direction}, at most {safe} mm is safe" if safe >= 1
                      else f"no {direction} motion is safe here; {away}")
            offered = Advice(safe_mm=safe) if safe >= 1 else None
            moved = f"after {along:.0f} mm"
        else:
            turned = math.degrees(along)
            safe = math.ceil(turned) - 1
            advice = (f"at most {safe} deg of this turn is safe" if safe >= 1
                      else f"no turn to the {signal.direction} is safe here; move straight away first")
            offered = Advice(safe_deg=safe) if safe >= 1 else None
            moved = f"after {turned:.0f} deg"
        reason = f"{signal.describe()}: the body ({body}) {what} {_where(point)} of the robot {moved}; {advice}"
        return Verdict(rule=self.name, valid=False, reason=reason,  # the advice's words end the reason
                       advice=offered.model_copy(update={"words_end": len(reason)}) if offered else None)

    def validate_motion(self, motion: Motion, context: ValidationContext) -> MotionVerdict:
        touched, hidden = self._contacts(motion, context)
        hits = [c for c in (touched, hidden) if c is not None]
        if not hits:
            return MotionVerdict(Verdict(rule=self.name, valid=True))
        time_s, what, point = min(hits, key=lambda c: c[0])
        body = context.robot.body(self.options.margin_mm).describe()
        verdict = Verdict(rule=self.name, valid=False, reason=(
            f"held {motion.duration_s:g} s, the body ({body}) {what} {_where(point)} of the robot "
            f"after {time_s:.2f} s"))
        kind: Literal["return", "unseen"] = "return" if touched is not None and touched[0] == time_s else "unseen"
        return MotionVerdict(verdict, time_s, kind, touched[0] if touched else None, hidden[0] if hidden else None)
