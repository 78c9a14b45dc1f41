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

A return the body already holds -- on its outline (Nav2 counts it outside) or inside -- counts only
once the motion takes the body deeper over it (:func:`~safeembodai_core.geometry.sweep.deeper_times`):
a robot in contact may back off it, into space the scan saw.

Only points within reach of the motion are looked at: the centre's travel plus the body's reach.
A refusal says what was touched, where, and how much of the motion is safe ("at most N mm is
safe", "at most N deg"). Beyond the paper: V(C) judges the beams within ±r of the heading only, so
it drives through a return just off the heading that the body sweeps, and accepts any turn.
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np

from safeembodai_core.geometry import Motion, contact_times
from safeembodai_core.geometry.sweep import near_path
from safeembodai_core.held_motion import MotionValidator, MotionVerdict
from safeembodai_core.models import Advice, ControlSignal, LidarScan, Straight, Verdict
from safeembodai_core.validation import ValidationContext

from .rules import checked_scan

_UNSEEN = ("no reading", "behind a return", "beyond the sensor's range")
_DEEPER = "goes deeper over a return of the scan"
_JUMP_STEPS = 2.0  # a neighbour this many sample steps farther leaves a shadow edge worth sampling
#: The farthest a judged motion's centre may travel (100 km); beyond it nothing is placed, so it is refused.
MAX_TRAVEL_MM = 1e8


def _rays(angles: np.ndarray, starts: np.ndarray, stops: np.ndarray, step: float,
          thin_rad: float | None = None) -> np.ndarray:
    """Samples every ``step`` mm along each beam from ``starts`` to ``stops`` (scan frame). With
    ``thin_rad`` (the beams' spacing, for neighbouring beams that are all unread) a ring of radius r
    keeps only every k-th beam, k = step / (r * thin_rad): samples about ``step`` apart across too."""
    counts = np.maximum(np.floor((stops - starts) / step).astype(int) + 1, 0)
    if not counts.sum():
        return np.empty((0, 2))
    beam = np.repeat(np.arange(len(angles)), counts)
    radii = starts[beam] + step * (np.arange(beam.size) - np.repeat(np.cumsum(counts) - counts, counts))
    if thin_rad is not None:
        every = np.maximum(1, np.floor(step / np.maximum(radii * thin_rad, 1e-9))).astype(int)
        index = np.rint(angles[beam] / thin_rad).astype(int)
        keep = index % every == 0
        beam, radii = beam[keep], radii[keep]
    return np.column_stack((radii * np.cos(angles[beam]), radii * np.sin(angles[beam])))


def scene(scan: LidarScan, reach_mm: float, step_mm: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The returns within ``reach_mm`` of the scan's origin, and the unseen samples with their kind
    (an index into ``_UNSEEN``), in the frame the scan was taken in (module docstring); samples inside
    the body where the scan was taken are still among them."""
    ranges = scan.ranges_mm
    angles = np.radians(scan.angles_deg)
    read = ~np.isnan(ranges)
    depth = np.where(read, np.minimum(ranges, scan.max_range_mm), np.nan)
    near = np.isfinite(ranges) & (ranges <= reach_mm)
    returns = np.column_stack((ranges[near] * np.cos(angles[near]), ranges[near] * np.sin(angles[near])))
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
                  math.radians(scan.increment_deg)),
            _rays(angles[edges], np.zeros(int(edges.sum())), np.full(int(edges.sum()), stop), step_mm)]))
        kinds.append(0)
    for neighbour in (np.roll(depth, -1), np.roll(depth, 1)):
        edge = read & ~np.isnan(neighbour) & (neighbour > depth + _JUMP_STEPS * step_mm) & (depth < reach_mm)
        if edge.any():
            parts.append(_rays(angles[edge], depth[edge] + step_mm, np.minimum(neighbour[edge], reach_mm), step_mm))
            kinds.append(1)
    if reach_mm >= scan.max_range_mm:  # the body can leave the disc the sensor saw: its rim where beams saw free
        rim = np.arange(0.0, 2 * math.pi, step_mm / scan.max_range_mm)
        beam = np.rint(np.degrees(rim) / scan.increment_deg).astype(int) % scan.beam_count
        rim = rim[read[beam] & (depth[beam] >= scan.max_range_mm)]
        parts.append(scan.max_range_mm * np.column_stack((np.cos(rim), np.sin(rim))))
        kinds.append(2)
    if not parts:
        return returns, np.empty((0, 2)), np.empty(0, dtype=int)
    labels = np.concatenate([np.full(len(p), k) for p, k in zip(parts, kinds)])
    return returns, np.concatenate(parts), labels


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
        if math.hypot(x, y) + body.reach_mm >= scan.max_range_mm:
            return [None, (0.0, f"touches space the scan did not see (the body reaches past the sensor's range of "
                                f"{scan.max_range_mm:g} mm)", here)]
        reach = math.hypot(x, y) + motion.centre_travel_mm + body.reach_mm + o.unseen_step_mm
        returns, unseen, labels = scene(scan, reach, o.unseen_step_mm)
        if scan.returns_mm is not None and len(scan.returns_mm):  # the unbinned returns as well
            exact = scan.returns_mm[~(np.hypot(scan.returns_mm[:, 0], scan.returns_mm[:, 1]) > reach)]
            returns = np.concatenate((returns, exact))
        touched = hidden = None
        if len(returns):
            planned = context.to_planned_frame(returns)
            times = contact_times(planned, motion, body, escape=True)
            if np.count_nonzero(np.isfinite(times)) >= o.min_points:
                order = np.argsort(times, kind="stable")
                held = bool(body.inside(planned[order[:1]])[0])
                what = _DEEPER if held else "touches a return of the scan"
                touched = (float(times[order[o.min_points - 1]]), what, planned[order[0]])
        if len(unseen):
            planned = context.to_planned_frame(unseen)
            keep = np.flatnonzero(near_path(planned, motion, body.reach_mm))
            keep = keep[~body.inside(unseen[keep])]  # where the robot stood when it scanned
            if keep.size:
                times = contact_times(planned[keep], motion, body)
                k = int(np.argmin(times))
                if np.isfinite(times[k]):
                    what = f"touches space the scan did not see ({_UNSEEN[labels[keep[k]]]})"
                    hidden = (float(times[k]), what, planned[keep[k]])
        return [touched, hidden]

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
