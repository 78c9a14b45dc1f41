"""Finding what moved between two LiDAR scans, in the room frame, and how fast.

Both scans are moved into the world (room) frame by the poses they were taken from, so walls and
balls land on themselves and cancel out. A return of the newer scan is **arrived** where the
older scan's beams passed beyond it (the older scan saw free space there: something came in);
a return of the older scan is **departed** where the newer scan sees beyond it. Returns are
grouped into clusters (neighbouring beams, gaps under ``cluster_gap_mm``); a cluster with at
least ``min_points`` arrived (or departed) returns is a mover, seen as a disc (:class:`Blob`)
fitted to the arc the sensor saw. Each arrived disc is paired with a departed disc it could have
come from (at most ``max_speed_mm_s`` away over the time between the scans): that pair gives the
velocity. By default pairs are taken greedily, nearest first; when movers are known to cruise at
``cruise_speed_mm_s``, as many pairs as can be made with the least total departure from the chord
such a mover drives over that time (:func:`chord_share`), so that movers following each other in
a column, or crossing, are not paired with each other's earlier positions, and a stopped mover
keeps its own short chord. An arrived disc with no partner (where it was was hidden, or out of
range) is a mover of unknown velocity. A mover coming along the line of sight hides where it was
behind where it is: a compact cluster of the older scan now hidden behind an arrived return
counts as departed too (a ball behind a mover can then be taken for where it came from).

Everything else -- returns consistent with the older scan, and returns the older scan could not
see (occluded, or beyond its range) -- is taken to be static: seen once, its motion is unknown.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

from safeembodai_core.geometry.frames import into_frame, out_of_frame
from safeembodai_core.models import LidarScan, Pose


@dataclass(frozen=True)
class Blob:
    """A moving obstacle as a disc in the room frame (mm, mm/s); ``velocity`` None: unknown.
    ``span_s``: the time between the two scans the velocity was measured over. ``wander_deg``,
    ``cruise_mm_s`` and ``chords``: what the trial's scans taught about it (:mod:`.learning`),
    None where nothing was learned (the rule's options then say)."""

    centre: np.ndarray
    radius_mm: float
    velocity: np.ndarray | None
    points: int
    span_s: float = 0.0
    wander_deg: float | None = None
    cruise_mm_s: float | None = None
    chords: int = 0


def _to_room(points: np.ndarray, pose: Pose) -> np.ndarray:
    return out_of_frame(points, (pose.x_mm, pose.y_mm, pose.heading_deg))


def _returns(scan: LidarScan) -> tuple[np.ndarray, np.ndarray]:
    """Beam indices with a return (finite range), and their points in the scan frame."""
    ranges = np.asarray(scan.ranges_mm, dtype=float)
    index = np.flatnonzero(np.isfinite(ranges))
    rad = np.radians(scan.angles_deg[index])
    return index, np.column_stack((ranges[index] * np.cos(rad), ranges[index] * np.sin(rad)))


def _seen_beyond(points_room: np.ndarray, scan: LidarScan, pose: Pose, tolerance_mm: float) -> np.ndarray:
    """Per room point: did ``scan`` (taken at ``pose``) see free space at it and beyond?

    True only where the beam nearest the point's bearing and both its neighbours read farther
    than the point by more than ``tolerance_mm`` (a no-return beam reads its range); a point
    beyond the sensor's range, or on a beam with no reading, is never seen beyond.
    """
    beam, distance = _local(points_room, scan, pose)
    n = scan.beam_count
    ranges = np.where(np.isposinf(scan.ranges_mm), scan.max_range_mm, scan.ranges_mm)
    reach = np.minimum(ranges[beam], np.minimum(ranges[(beam - 1) % n], ranges[(beam + 1) % n]))
    return (distance < scan.max_range_mm) & (reach > distance + tolerance_mm)  # nan compares False


def _clusters(index: np.ndarray, points: np.ndarray, beams: int, gap_mm: float) -> list[np.ndarray]:
    """Runs of neighbouring beams whose consecutive returns are closer than ``gap_mm`` (positions
    into ``index``); the run across beam 0 is joined."""
    if index.size == 0:
        return []
    breaks = (np.diff(index) != 1) | (np.hypot(*np.diff(points, axis=0).T) > gap_mm)
    runs = np.split(np.arange(index.size), np.flatnonzero(breaks) + 1)
    if (len(runs) > 1 and index[0] == 0 and index[-1] == beams - 1
            and math.hypot(*(points[0] - points[-1])) <= gap_mm):
        runs = [np.concatenate((runs[-1], runs[0]))] + runs[1:-1]
    return runs


def _disc(points_room: np.ndarray, sensor: np.ndarray, beam_gap_mm: float,
          max_size_mm: float) -> tuple[np.ndarray, float]:
    """The disc whose near arc the sensor saw as ``points_room``: radius half the arc's extent
    (plus half a beam's spacing), centre that far behind the nearest point, on the arc's bearing."""
    spread = points_room - points_room.mean(axis=0)
    extent = 2.0 * float(np.max(np.hypot(spread[:, 0], spread[:, 1]))) if len(points_room) > 1 else 0.0
    radius = min(extent / 2.0 + beam_gap_mm / 2.0, max_size_mm / 2.0)
    towards = points_room.mean(axis=0) - sensor
    unit = towards / max(float(np.hypot(*towards)), 1e-9)
    near = float(np.min(np.hypot(*(points_room - sensor).T)))
    return sensor + unit * (near + radius), radius


@dataclass(frozen=True)
class TrackingSettings:
    tolerance_mm: float = 100.0
    cluster_gap_mm: float = 150.0
    min_points: int = 2
    max_size_mm: float = 800.0
    max_speed_mm_s: float = 1000.0
    cruise_speed_mm_s: float | None = None  # pair by the expected chord instead of nearest first
    wander_deg: float = 25.0  # the movers' heading random walk (for the expected chord)


def chord_share(wander_deg: float, span_s: float) -> float:
    """The root-mean-square chord of a mover at constant speed whose heading drifts as a random walk
    of ``wander_deg`` per square-root second, as a share of the path it drove over ``span_s``:
    sqrt(2 (kT - 1 + exp(-kT))) / kT with k = sigma**2 / 2 (1 for a straight course)."""
    k_t = math.radians(wander_deg) ** 2 / 2.0 * max(span_s, 0.0)
    if k_t < 1e-12:
        return 1.0
    return min(1.0, math.sqrt(2.0 * (k_t + math.expm1(-k_t))) / k_t)


@functools.lru_cache(maxsize=256)
def _chord_quantile(wander_deg: float, span_s: float, quantile: float) -> float:
    walks, steps = 2000, 100
    rng = np.random.default_rng(0)
    sigma = math.radians(wander_deg) * math.sqrt(span_s / steps)
    heading = np.cumsum(sigma * rng.standard_normal((walks, steps)), axis=1)
    chord = np.hypot(np.cos(heading).mean(axis=1), np.sin(heading).mean(axis=1))
    return float(np.quantile(chord, quantile))


def chord_share_quantile(wander_deg: float, span_s: float, quantile: float) -> float:
    """The ``quantile`` of the chord share (chord over path) of a mover at constant speed whose
    heading drifts as a random walk of ``wander_deg`` per square-root second over ``span_s``: from
    2,000 simulated walks of 100 steps (fixed draws; cached per 0.1 degree and 0.1 s)."""
    wander, span = round(wander_deg, 1), round(max(span_s, 0.0), 1)
    if wander <= 0 or span <= 0:
        return 1.0
    return _chord_quantile(wander, span, quantile)


def _local(points_room: np.ndarray, scan: LidarScan, pose: Pose) -> tuple[np.ndarray, np.ndarray]:
    """Per room point: the beam of ``scan`` (taken at ``pose``) nearest its bearing, and its distance."""
    local = into_frame(points_room, (pose.x_mm, pose.y_mm, pose.heading_deg))
    x, y = local[:, 0], local[:, 1]
    beam = np.rint(np.degrees(np.arctan2(y, x)) / scan.increment_deg).astype(int) % scan.beam_count
    return beam, np.hypot(x, y)


def _shadowed(points_room: np.ndarray, scan: LidarScan, pose: Pose, arrived_beams: np.ndarray,
              tolerance_mm: float) -> np.ndarray:
    """Per room point of the older scan: is it now hidden behind an arrived return? (A mover
    coming along the line of sight hides where it was.)"""
    beam, distance = _local(points_room, scan, pose)
    ranges = scan.ranges_mm[beam]
    return arrived_beams[beam] & np.isfinite(ranges) & (ranges < distance - tolerance_mm)


def _movers(scan: LidarScan, pose: Pose, moved_of, s: TrackingSettings,
            compact_moved_of=None) -> tuple[list[tuple[np.ndarray, float, int]], np.ndarray]:
    """Discs of ``scan``'s clusters with at least ``min_points`` returns ``moved_of`` marks (a
    function of the room points), and which beams hold a marked return. ``compact_moved_of``
    marks more returns, counted for clusters no larger than a mover only."""
    marked = np.zeros(scan.beam_count, dtype=bool)
    index, local = _returns(scan)
    if index.size == 0:
        return [], marked
    room = _to_room(local, pose)
    moved = moved_of(room)
    marked[index[moved]] = True
    extra = compact_moved_of(room) if compact_moved_of is not None else np.zeros(len(room), dtype=bool)
    sensor = np.array([pose.x_mm, pose.y_mm])
    discs = []
    for run in _clusters(index, local, scan.beam_count, s.cluster_gap_mm):
        members = room[run]
        spread = members - members.mean(axis=0)
        compact = 2.0 * float(np.max(np.hypot(spread[:, 0], spread[:, 1]))) <= s.max_size_mm
        count = np.count_nonzero(moved[run] | (extra[run] if compact else False))
        if count < s.min_points:
            continue
        if not compact:
            members = room[run[moved[run]]]  # a mover beside a wall: its own returns only
        distance = float(np.hypot(*(members.mean(axis=0) - sensor)))
        beam_gap = distance * math.radians(scan.increment_deg)
        centre, radius = _disc(members, sensor, beam_gap, s.max_size_mm)
        discs.append((centre, radius, len(members)))
    return discs, marked


def _greedy(cost: np.ndarray, feasible: np.ndarray) -> dict[int, int]:
    """Pairs (arrived -> departed) taken greedily, lowest cost first (with the gaps: nearest first)."""
    partner: dict[int, int] = {}
    for i, j in sorted(zip(*np.nonzero(feasible)), key=lambda ij: (cost[ij], ij)):
        if int(i) not in partner and int(j) not in partner.values():
            partner[int(i)] = int(j)
    return partner


_EXACT_DEPARTED = 12  # more departed discs than this: greedy pairing (the exact search is 2**n)

#: A partial pairing of the exact search: (pairs made, -total cost), and the pairs (arrived -> departed).
_Scored = tuple[tuple[int, float], dict[int, int]]


def _least_total(cost: np.ndarray, feasible: np.ndarray) -> dict[int, int]:
    """Pairs (arrived -> departed) as many as can be made, and among those the least total cost: a
    search over subsets of the departed discs (a greedy best-first pass beyond ``_EXACT_DEPARTED`` of
    them). Greedy best-first alone lets one good pair take the partner another mover needs: a
    stopped mover near where a cruising one was gets the cruiser's earlier position."""
    arrived, departed = cost.shape
    if departed > _EXACT_DEPARTED:
        return _greedy(cost, feasible)
    # best[mask]: (pairs made, -total cost) over the first i arrived discs, using the departed in mask
    best: dict[int, _Scored] = {0: ((0, 0.0), {})}
    for i in range(arrived):
        step: dict[int, _Scored] = {}
        for mask, (score, pairs) in best.items():
            options = [(mask, score, pairs)]
            options += [(mask | 1 << j, (score[0] + 1, score[1] - float(cost[i, j])), {**pairs, i: j})
                        for j in range(departed) if feasible[i, j] and not mask & 1 << j]
            for key, value, chosen in options:
                if key not in step or value > step[key][0]:
                    step[key] = (value, chosen)
        best = step
    return max(best.values(), key=lambda entry: entry[0])[1] if best else {}


def find_movers(scan: LidarScan, pose: Pose, time_s: float, before: LidarScan, before_pose: Pose,
                before_time_s: float, settings: TrackingSettings = TrackingSettings()) -> list[Blob]:
    """The movers of ``scan`` (positions now), with velocities from ``before`` where paired."""
    dt = time_s - before_time_s
    arrived, beams = _movers(scan, pose, lambda room: _seen_beyond(room, before, before_pose, settings.tolerance_mm),
                             settings)
    if not arrived:
        return []
    departed: list[tuple[np.ndarray, float, int]] = []
    if dt > 0:
        departed, _ = _movers(before, before_pose, lambda room: _seen_beyond(room, scan, pose, settings.tolerance_mm),
                              settings, lambda room: _shadowed(room, scan, pose, beams, settings.tolerance_mm))
    gaps = np.array([[float(np.hypot(*(a[0] - d[0]))) for d in departed] for a in arrived]).reshape(len(arrived), -1)
    feasible = gaps <= settings.max_speed_mm_s * dt
    if settings.cruise_speed_mm_s is None:
        partner = _greedy(gaps, feasible)
    else:
        expected = settings.cruise_speed_mm_s * dt * chord_share(settings.wander_deg, dt)
        partner = _least_total(np.abs(gaps - expected), feasible)
    blobs = []
    for i, (centre, radius, count) in enumerate(arrived):
        velocity = (centre - departed[partner[i]][0]) / dt if i in partner else None
        blobs.append(Blob(centre=centre, radius_mm=radius, velocity=velocity, points=count, span_s=max(dt, 0.0)))
    return blobs
