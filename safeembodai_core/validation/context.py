"""Safety validation machinery shared by the loop and the library API.

Validators judge one control signal at a time. A plan C_i = [g_i1, ..., g_in] is checked in
order against the robot's *planned* pose: before judging g_ij the context is advanced by the
exact motion of g_i1..g_i(j-1). A rule like the paper's V(C) therefore checks the second signal
of "turn left 45, straight 300" against the beams that will face forward after the turn, not the
ones facing forward now.

Away from the scan's own position rules judge the *measured points* (the scan's returns and
free-space bounds moved into the planned frame); a direction counts as unknown only where the
sensor gave no reading (a ``nan`` beam), never because moved points leave gaps between beams.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass, replace
from typing import Iterable, Literal, Sequence

import numpy as np

from ..models import DEFAULT_LIMITS, ControlLimits, ControlSignal, LidarScan, Pose, Turn, Verdict
from ..contracts.robot import RobotSpec
from ..geometry.frames import advance, compose, into_frame, out_of_frame, wrap_deg

_UNKNOWN_RAY_STEP_MM = 50.0
_EDGE_EPS = 1e-9
SectorKind = Literal["return", "free_bound", "unread"]
_KINDS: tuple[SectorKind, ...] = ("return", "free_bound", "unread")


@dataclass(frozen=True)
class SectorReading:
    """The nearest thing within a sector around the planned pose.

    ``kind`` is ``return`` (an echo), ``free_bound`` (a no-return beam: free only up to the
    sensor's range from where the scan was taken) or ``unread`` (on a beam with no reading, which
    rules must treat as a possible obstacle). ``bearing_deg`` is relative to the planned heading.
    """

    distance_mm: float
    bearing_deg: float
    kind: SectorKind


@dataclass(frozen=True)
class PastScan:
    """A scan the robot took at an earlier step of the same trial (for rules about motion).

    ``scan`` is the scan as the validators of that step saw it (as attackers left it), ``pose``
    where the robot really stood then (world frame, as the environment reported it) and
    ``sim_time_s`` the environment's simulated clock when it was read.
    """

    scan: LidarScan
    pose: Pose
    sim_time_s: float


@dataclass(frozen=True)
class ValidationContext:
    """What a validator knows when it judges one signal of a plan (``docs/plugin_hooks.md``).

    * ``scan``: the LiDAR scan read at the start of the step (as attackers left it: a spoofed
      sensor fools the rules too), or None when the environment has no LiDAR.
    * ``robot``: the robot's body (:class:`RobotSpec`, mm).
    * ``limits``: the actuation limits of the scenario.
    * ``offset``: ``(x_mm, y_mm, heading_deg)``, the planned pose reached by the plan's earlier
      signals, in the *scan frame* (the robot frame where the scan was taken: x forward, y left,
      heading counter-clockwise). ``(0, 0, 0)`` for a plan's first signal.
    * ``start_pose``: where the robot really is at the start of the step, in the environment's
      world (room) frame, as the environment reports it -- never the attacked copy an attacker
      may alter; None when the environment reports no pose. :attr:`planned_pose` is it moved by
      ``offset``.
    * ``sim_time_s``: the simulated clock when ``scan`` was read (the observation's), or None.
    * ``history``: the trial's earlier scans with their poses and times (:class:`PastScan`),
      oldest first; only steps whose observation had a scan and a pose. Empty on step 1 and for
      library users who pass none.
    * ``earlier_signals``: the signals of the plan judged before this one (what ``offset`` sums
      up, in order): a rule about time needs their durations, which ``offset`` cannot give.
    * ``later_signals``: the plan's signals after this one, in order (empty for its last signal):
      a rule about where the plan leaves the robot judges that once, with the last signal.
    * ``answer_s``: the clock when the answer being judged arrived (its plan starts then), on the
      clock of ``sim_time_s``; None when unknown (rules about time then estimate the wait). With
      an arm's ``fresh_scan`` it equals ``sim_time_s``: the scan was read as the answer arrived.
    """

    scan: LidarScan | None
    robot: RobotSpec = RobotSpec()
    limits: ControlLimits = DEFAULT_LIMITS
    offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
    start_pose: Pose | None = None
    sim_time_s: float | None = None
    history: tuple[PastScan, ...] = ()
    earlier_signals: tuple[ControlSignal, ...] = ()
    later_signals: tuple[ControlSignal, ...] = ()
    answer_s: float | None = None

    def advanced(self, signal: ControlSignal) -> "ValidationContext":
        """The context after ``signal`` is executed exactly as commanded."""
        earlier = self.earlier_signals + (signal,)
        if isinstance(signal, Turn):
            return replace(self, offset=advance(self.offset, turn_deg=signal.signed_angle_deg), earlier_signals=earlier)
        return replace(self, offset=advance(self.offset, signal.signed_distance_mm), earlier_signals=earlier)

    @property
    def planned_pose(self) -> Pose | None:
        """The planned pose in the world (room) frame: ``start_pose`` moved by ``offset``; None
        without a ``start_pose``. Its heading is wrapped to [-180, 180)."""
        if self.start_pose is None:
            return None
        start = self.start_pose
        x, y, heading = compose((start.x_mm, start.y_mm, start.heading_deg), self.offset)
        return Pose(x_mm=x, y_mm=y, heading_deg=heading)

    @property
    def at_scan_position(self) -> bool:
        """True while the plan has only turned in place: the scan's beams still start here."""
        return math.hypot(self.offset[0], self.offset[1]) < 1e-9

    def require_scan(self, rule: str) -> LidarScan:
        if self.scan is None:
            raise ValueError(f"validator {rule!r} needs a LiDAR scan and none was given")
        return self.scan

    def to_planned_frame(self, points: np.ndarray) -> np.ndarray:
        """(M, 2) points from the frame the scan was taken in to the planned robot frame."""
        return into_frame(points, self.offset)

    def to_scan_frame(self, points: np.ndarray) -> np.ndarray:
        """(M, 2) points from the planned robot frame back to the frame the scan was taken in."""
        return out_of_frame(points, self.offset)

    def points_at_pose(self, include_free_bound: bool = True) -> np.ndarray:
        """LiDAR returns as (M, 2) points in the planned robot frame (mm)."""
        scan = self.require_scan("points_at_pose")
        return self.to_planned_frame(scan.points(include_free_bound=include_free_bound))

    def unknown_points_at_pose(self) -> np.ndarray:
        """Points sampled along every missing (``nan``) beam, in the planned robot frame.

        A missing beam says nothing about its direction, so rules treat these samples as possible
        obstacles: conservative, never optimistic.
        """
        scan = self.require_scan("unknown_points_at_pose")
        missing = np.flatnonzero(np.isnan(scan.ranges_mm))
        if missing.size == 0:
            return np.empty((0, 2))
        radii = np.arange(0.0, scan.max_range_mm + _UNKNOWN_RAY_STEP_MM, _UNKNOWN_RAY_STEP_MM)
        rad = np.radians(scan.angles_deg[missing])
        xs = np.outer(np.cos(rad), radii).ravel()
        ys = np.outer(np.sin(rad), radii).ravel()
        return self.to_planned_frame(np.column_stack((xs, ys)))

    def _unread_segments(self, skip_mm: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
        """Every ``nan`` beam's ray, from ``skip_mm`` to the sensor's range, as segments (starts,
        ends) in the planned frame."""
        scan = self.require_scan("unread beams")
        rad = np.radians(scan.angles_deg[np.isnan(scan.ranges_mm)])
        unit = np.column_stack((np.cos(rad), np.sin(rad)))
        return self.to_planned_frame(skip_mm * unit), self.to_planned_frame(scan.max_range_mm * unit)

    def nearest_in_sector(self, centre_deg: float, half_width_deg: float) -> SectorReading | None:
        """The nearest measured point within ``half_width_deg`` (<= 90) of ``centre_deg`` (both
        relative to the planned heading), seen from the planned pose; ``None`` if there is none.

        At the scan's position (the plan has only turned) this is the paper's l(θ) over the
        sector: the beams within it, a no-return beam free up to the sensor's range, a ``nan`` beam
        unread at distance 0. After a translation it is the nearest of the returns and free-space
        bounds (``LidarScan.points(include_free_bound=True)``) whose bearing from the planned pose
        lies in the sector, and of the sector's part of every ``nan`` beam's ray beyond the body
        (the robot stood there when the scan was taken), computed exactly rather than sampled.
        """
        scan = self.require_scan("nearest_in_sector")
        heading = self.offset[2]
        if self.at_scan_position:
            beams = scan.sector(heading + centre_deg, half_width_deg)
            if beams.size == 0:
                return None
            ranges = scan.ranges_mm[beams]
            kinds = np.where(np.isnan(ranges), 2, np.where(np.isposinf(ranges), 1, 0))
            ranges = np.where(np.isnan(ranges), 0.0, np.minimum(ranges, scan.max_range_mm))
            k = int(np.lexsort((-kinds, ranges))[0])  # the nearest; at a tie the unread one
            bearing = wrap_deg(scan.angles_deg[beams[k]] - heading)
            return SectorReading(float(ranges[k]), float(bearing), _KINDS[kinds[k]])
        best: SectorReading | None = None
        normals = _sector_normals(centre_deg, half_width_deg)
        points = self.points_at_pose(include_free_bound=True)
        free = np.isposinf(scan.ranges_mm[~np.isnan(scan.ranges_mm)])
        distance = np.hypot(points[:, 0], points[:, 1])
        inside = np.all(points @ normals.T >= -_EDGE_EPS * (1.0 + distance)[:, None], axis=1)
        if inside.any():
            k = np.flatnonzero(inside)[np.argmin(distance[inside])]
            best = SectorReading(float(distance[k]), math.degrees(math.atan2(points[k, 1], points[k, 0])),
                                 "free_bound" if free[k] else "return")
        starts, ends = self._unread_segments(min(self.robot.width_mm, self.robot.length_mm) / 2)
        if len(starts):
            reach, nearest = _segments_in_sector(starts, ends, normals)
            k = int(np.argmin(reach))
            if np.isfinite(reach[k]) and (best is None or reach[k] <= best.distance_mm):
                best = SectorReading(float(reach[k]), math.degrees(math.atan2(nearest[k, 1], nearest[k, 0])), "unread")
        return best

    def ranges_at_pose(self) -> np.ndarray:
        """The scan as it would read from the planned pose: ``inf`` free, ``nan`` unknown.

        At the scan's position this is the scan, its beams shifted after a pure rotation (the
        nearer of two neighbours when the angle falls between beams). After a translation each
        beam direction reads where the space the sensor saw free ends along it: the nearest of the
        returns and free-space bounds binned to that direction, and the point where its ray meets
        the outline joining neighbouring beams' ends (an obstacle, the sensor's range, or the edge
        of a shadow). No direction reads ``inf`` then. It reads ``nan`` only where a ``nan`` beam's
        ray comes first, or where the ray meets nothing the sensor measured (it leaves through the
        gap a ``nan`` beam leaves in the outline, or the pose lies outside the space seen). To judge
        a motion prefer ``nearest_in_sector`` or the points themselves: they need no binning.
        """
        scan = self.require_scan("ranges_at_pose")
        heading = self.offset[2]
        n, inc = scan.beam_count, scan.increment_deg
        if self.at_scan_position:
            shift = (heading / inc) % n
            low = int(math.floor(shift)) % n
            if abs(shift - round(shift)) < 1e-9:
                return np.roll(scan.ranges_mm, -int(round(shift)) % n)
            return np.minimum(np.roll(scan.ranges_mm, -low), np.roll(scan.ranges_mm, -(low + 1) % n))
        read = ~np.isnan(scan.ranges_mm)
        ends = self.to_planned_frame(scan.points(include_free_bound=True))  # one per read beam, in order
        following = np.roll(read, -1)[read]  # the next beam (counter-clockwise) was read too
        outline = _ray_hits(n, inc, ends[following], np.roll(ends, -1, axis=0)[following])
        binned = _binned(ends, n, inc)
        measured = np.fmin(np.where(np.isinf(binned), np.nan, binned), outline)
        unknown = _binned(self.unknown_points_at_pose(), n, inc)
        starts, stops = self._unread_segments()
        if len(starts):
            unknown = np.fmin(unknown, _ray_hits(n, inc, starts, stops))
        return np.where(np.isnan(measured) | (unknown <= measured), np.nan, measured)


class Validator(ABC):
    """A safety rule applied to each control signal before execution (also importable from
    :mod:`safeembodai_core.contracts.components`, with the other interfaces)."""

    @abstractmethod
    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        """Judge ``signal`` given the (planned) robot state in ``context``.

        The verdict's ``reason`` is shown to the LLM on a retry: say what was wrong and by how much.
        """


def validate_plan(
    signals: Sequence[ControlSignal],
    context: ValidationContext,
    rules: Iterable[tuple[str, Validator]],
) -> list[Verdict]:
    """Judge each signal of a plan with every rule, advancing the planned pose between signals."""
    rules = list(rules)
    signals = list(signals)
    verdicts: list[Verdict] = []
    for index, signal in enumerate(signals):
        context = replace(context, later_signals=tuple(signals[index + 1:]))
        for name, rule in rules:
            try:
                verdict = rule.validate(signal, context)
            except Exception as error:  # a broken rule refuses: it never lets a command through
                verdict = Verdict(rule=name, valid=False, reason=f"rule failed ({type(error).__name__}: {error})")
            if not isinstance(verdict, Verdict):
                verdict = Verdict(rule=name, valid=False,
                                  reason=f"rule returned {type(verdict).__name__}, not a Verdict")
            verdicts.append(verdict.model_copy(update={"signal_index": index, "rule": name}))
        context = context.advanced(signal)
    return verdicts



def _sector_normals(centre_deg: float, half_width_deg: float) -> np.ndarray:
    """Inward normals of the sector's two edges: a point p is inside iff both dot products are >= 0."""
    a, b = math.radians(centre_deg + half_width_deg), math.radians(centre_deg - half_width_deg)
    return np.array([[math.sin(a), -math.cos(a)], [-math.sin(b), math.cos(b)]])


def _segments_in_sector(starts: np.ndarray, ends: np.ndarray, normals: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per segment, the distance from the origin of its nearest point inside the sector (``inf`` if
    it misses the sector), and that point."""
    edge = ends - starts
    low, high = np.zeros(len(starts)), np.ones(len(starts))
    for normal in normals:
        at, slope = starts @ normal, edge @ normal
        flat = np.abs(slope) < 1e-12
        bound = np.where(flat, 0.0, -at / np.where(flat, 1.0, slope))
        low = np.where(~flat & (slope > 0), np.maximum(low, bound), low)
        high = np.where(~flat & (slope < 0), np.minimum(high, bound), high)
        high = np.where(flat & (at < -_EDGE_EPS), -1.0, high)
    length2 = np.maximum(np.einsum("ij,ij->i", edge, edge), 1e-12)
    t = np.clip(-np.einsum("ij,ij->i", starts, edge) / length2, low, np.maximum(low, high))
    nearest = starts + t[:, None] * edge
    distance = np.where(low <= high, np.hypot(nearest[:, 0], nearest[:, 1]), np.inf)
    return distance, nearest


def _binned(points: np.ndarray, n: int, inc: float) -> np.ndarray:
    """Per beam direction from the origin, the distance of the nearest point binned to it (inf: none)."""
    binned = np.full(n, np.inf)
    if points.size:
        index = np.rint(np.degrees(np.arctan2(points[:, 1], points[:, 0])) / inc).astype(int) % n
        np.minimum.at(binned, index, np.hypot(points[:, 0], points[:, 1]))
    return binned


def _ray_hits(n: int, inc: float, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Per beam direction k * inc from the origin, the distance to the first segment its ray meets
    (``nan``: none). Each segment is tried only against the rays within the angle it spans."""
    result = np.full(n, np.inf)
    if len(starts):
        a0 = np.degrees(np.arctan2(starts[:, 1], starts[:, 0]))
        span = wrap_deg(np.degrees(np.arctan2(ends[:, 1], ends[:, 0])) - a0)
        first = np.ceil(np.minimum(a0, a0 + span) / inc - 1e-9).astype(int)
        counts = np.maximum(np.floor(np.maximum(a0, a0 + span) / inc + 1e-9).astype(int) - first + 1, 0)
        segment = np.repeat(np.arange(len(starts)), counts)
        k = first[segment] + np.arange(segment.size) - np.repeat(np.cumsum(counts) - counts, counts)
        rad = np.radians(k * inc)
        ux, uy = np.cos(rad), np.sin(rad)
        ax, ay = starts[segment, 0], starts[segment, 1]
        ex, ey = ends[segment, 0] - ax, ends[segment, 1] - ay
        denom = ux * ey - uy * ex
        ok = np.abs(denom) > 1e-12
        safe = np.where(ok, denom, 1.0)
        t, along = (ax * ey - ay * ex) / safe, (ax * uy - ay * ux) / safe
        hit = ok & (t >= 0) & (along >= -1e-9) & (along <= 1 + 1e-9)
        np.minimum.at(result, k[hit] % n, t[hit])
    return np.where(np.isinf(result), np.nan, result)


__all__ = ["PastScan", "SectorReading", "ValidationContext", "validate_plan"]
