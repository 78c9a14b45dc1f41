"""``moving_obstacles``: refuse a motion that drives into where a mover may be by then.

The rule compares the step's scan with the latest earlier scan of the trial
(``ValidationContext.history``), both in the room frame, to find the returns that moved
(:mod:`.tracking`) and their velocities. The robot's motion is timed with the rule's own model:
nothing moves for the think time after the scan (the LLM deciding), then the plan's signals run
one after the other, straights at ``robot_speed_mm_s`` and turns at ``robot_turn_rate_deg_s``.
Every mover gets ``futures`` possible courses (:mod:`.futures`): wandering around its measured
velocity (``wander_deg`` per square-root second; 0 gives the straight course), optionally
stopping for the robot ahead (``movers_yield_mm``). A ``straight`` is refused when at least
``max_risk`` of one mover's courses come, at some moment of it (sampled every ``sample_s``),
within ``margin_mm + margin_growth_mm_s * t`` of the robot's body, t being the time since the
scan, and the motion brings the body nearer to them than standing still would.

What the rule assumes:

* a return seen once -- on step 1, in a static scene, or where the earlier scan could not see
  (occluded, out of range) -- is static: this rule never refuses because of it (other rules
  judge where things are now);
* a mover whose earlier position was not seen (it came out of a shadow) has unknown velocity: its
  courses fan out all the way round at ``unknown_speed_mm_s``;
* a mover wanders as a random walk; one that turns on the spot at a wall, or behaves otherwise,
  is covered only as far as the courses' spread covers it (``docs/defences.md``);
* a turn in place is always accepted: the body does not leave its circle, so refusing it keeps
  no mover away (the straights that follow are judged at the times they will run); likewise a
  course counts against a straight only if the motion brings the body nearer to it than standing
  still for the same time would (least distance over the motion): a mover bound to reach the
  robot where it waits is the mover's doing (``struck``), and stepping out of its way must pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from safeembodai_core.components import Validator
from safeembodai_core.models import ControlSignal, Straight, Turn, Verdict
from safeembodai_core.validation import ValidationContext

from .futures import WanderingFutures, WanderSettings, yielding
from .rules import checked_scan, direction_words
from .tracking import Blob, TrackingSettings, find_movers

_WORSE_MM = 1.0  # a motion "brings the body closer" only by more than this


@dataclass(frozen=True)
class Sweep:
    """A straight against a mover's courses: the sampled moments (s after the scan), the distance
    driven by each, the courses' centres (courses, moments, 2), which course is inside the safety
    margin at which moment, and which courses count against the motion (met, and nearer than
    standing still would come)."""

    times: np.ndarray
    driven: np.ndarray
    where: np.ndarray
    inside: np.ndarray
    counted: np.ndarray


@dataclass(frozen=True)
class Meeting:
    """A straight meeting a mover's courses: the first sampled moment one counts (s after the
    scan), the distance driven by then, and the share of the mover's courses that count."""

    when_s: float
    driven_mm: float
    blob: Blob
    share: float


class MovingObstaclesRule(Validator):
    """Predicts movers from consecutive scans; refuses straights whose sweep meets one."""

    name = "moving_obstacles"

    def __init__(self, options) -> None:
        self.options = options
        self.tracking = TrackingSettings(
            tolerance_mm=options.static_tolerance_mm, cluster_gap_mm=options.cluster_gap_mm,
            min_points=options.min_moved_points, max_size_mm=options.max_obstacle_mm,
            max_speed_mm_s=options.max_obstacle_speed_mm_s, cruise_speed_mm_s=options.cruise_speed_mm_s,
            wander_deg=options.wander_deg)
        self.futures = WanderingFutures(WanderSettings(
            wander_deg=options.wander_deg, count=options.futures, step_s=options.sample_s,
            unknown_speed_mm_s=options.unknown_speed_mm_s, cruise_speed_mm_s=options.cruise_speed_mm_s,
            still_mm=options.static_tolerance_mm, seed=options.seed))
        self._cache: tuple | None = None

    # -- what the scans say ---------------------------------------------------------------------

    def movers(self, context: ValidationContext) -> tuple[list[Blob], float]:
        """The movers of the context's scan, and the think time the rule assumes (s)."""
        latest = context.history[-1].scan if context.history else None
        cached = self._cache
        # the scans themselves, compared by identity and held by the cache (an id could be reused)
        if (cached is not None and cached[0] is context.scan and cached[1] is latest
                and cached[2] == (context.start_pose, context.sim_time_s)):
            return cached[3], cached[4]
        blobs: list[Blob] = []
        usable = [past for past in context.history
                  if context.sim_time_s is not None
                  and 0 < context.sim_time_s - past.sim_time_s <= self.options.max_scan_gap_s]
        if usable and context.start_pose is not None:
            past = usable[-1]
            blobs = find_movers(context.scan, context.start_pose, context.sim_time_s,
                                past.scan, past.pose, past.sim_time_s, self.tracking)
        think = self.think_time_s(context)
        self._cache = (context.scan, latest, (context.start_pose, context.sim_time_s), blobs, think)
        return blobs, think

    def think_time_s(self, context: ValidationContext) -> float:
        """The option, or an estimate from the observation times: over consecutive observations,
        the least of (time between them - the least time the pose change needs at the rule's
        speeds), an upper bound on the think time when the world adds one per step."""
        o = self.options
        if o.think_time_s is not None:
            return o.think_time_s
        if context.start_pose is None or context.sim_time_s is None or not context.history:
            return 0.0
        chain = [(p.pose, p.sim_time_s) for p in context.history] + [(context.start_pose, context.sim_time_s)]
        bounds = []
        for (a, ta), (b, tb) in zip(chain, chain[1:]):
            turned = abs((b.heading_deg - a.heading_deg + 180.0) % 360.0 - 180.0)
            need = math.hypot(b.x_mm - a.x_mm, b.y_mm - a.y_mm) / o.robot_speed_mm_s + turned / o.robot_turn_rate_deg_s
            if 0 < tb - ta <= o.max_scan_gap_s:
                bounds.append(tb - ta - need)
        return max(0.0, min(bounds)) if bounds else 0.0

    def start_s(self, context: ValidationContext) -> float:
        """When the signal being judged starts, in seconds after the scan: the think time, then
        the plan's earlier signals at the rule's speeds."""
        return self.movers(context)[1] + sum(self.duration_s(s) for s in context.earlier_signals)

    def duration_s(self, signal: ControlSignal) -> float:
        if isinstance(signal, Straight):
            return signal.distance / self.options.robot_speed_mm_s
        return signal.angle / self.options.robot_turn_rate_deg_s

    # -- the check ------------------------------------------------------------------------------

    def sweep(self, context: ValidationContext, signal: Straight, blob: Blob, start_s: float) -> Sweep:
        """The straight (starting ``start_s`` after the scan) against every course of ``blob``."""
        o = self.options
        pose = context.planned_pose
        duration = self.duration_s(signal)
        times = start_s + np.linspace(0.0, duration, max(2, int(math.ceil(duration / o.sample_s)) + 1))
        driven = (times - start_s) * o.robot_speed_mm_s
        rad = math.radians(pose.heading_deg)
        sign = 1.0 if signal.direction == "forward" else -1.0
        robot = np.column_stack((pose.x_mm + sign * driven * math.cos(rad), pose.y_mm + sign * driven * math.sin(rad)))
        if o.movers_yield_mm > 0:
            # a yielding mover reacts to where the robot has been since the scan, not only to this
            # straight; standing still, the robot would be seen elsewhere, so those courses differ
            before = np.arange(0.0, start_s, o.sample_s)
            track = self._track_before(context, before)
            where, heading = self.futures.courses(blob, np.concatenate((before, times)))

            def held(robot_track: np.ndarray) -> np.ndarray:
                return yielding(where, heading, np.concatenate((track, robot_track)), context.robot.radius_mm,
                                blob.radius_mm, o.movers_yield_mm, o.movers_yield_deg)[:, len(before):]

            moving, still = held(robot), held(np.repeat(robot[:1], len(times), axis=0))
        else:
            moving = still = self.futures.at(blob, times)  # (courses, times, 2)
        reach = context.robot.radius_mm + blob.radius_mm + o.margin_mm + o.margin_growth_mm_s * times
        distance = np.hypot(*np.moveaxis(robot[None] - moving, -1, 0))
        standing = np.hypot(*np.moveaxis(robot[0][None, None] - still, -1, 0))
        inside = distance < reach
        closer = distance.min(axis=1) < standing.min(axis=1) - _WORSE_MM
        return Sweep(times=times, driven=driven, where=moving, inside=inside, counted=inside.any(axis=1) & closer)

    def _track_before(self, context: ValidationContext, times: np.ndarray) -> np.ndarray:
        """Where the robot's centre is at ``times`` before this straight: at the start pose through
        the think time, then along the plan's earlier signals at the rule's speeds."""
        pose = context.start_pose
        x, y, heading, t = pose.x_mm, pose.y_mm, pose.heading_deg, self.movers(context)[1]
        ts, xs, ys = [0.0, t], [x, x], [y, y]
        for earlier in context.earlier_signals:
            t += self.duration_s(earlier)
            if isinstance(earlier, Straight):
                rad = math.radians(heading)
                x, y = x + earlier.signed_distance_mm * math.cos(rad), y + earlier.signed_distance_mm * math.sin(rad)
            else:
                heading += earlier.signed_angle_deg
            ts.append(t)
            xs.append(x)
            ys.append(y)
        return np.column_stack((np.interp(times, ts, xs), np.interp(times, ts, ys)))

    def first_meeting(self, context: ValidationContext, signal: Straight, blobs: list[Blob], start_s: float
                      ) -> Meeting | None:
        """How the straight meets the movers' courses: for the mover whose courses it drives into
        most, the share of them it meets and the first sampled moment it does; None when no
        mover's share reaches ``max_risk``. A course on which the robot standing still (over the
        same time) comes at least as close is not counted: refusing would not keep that mover
        away, and a motion that gets out of its way must pass."""
        best: Meeting | None = None
        for blob in blobs:
            sweep = self.sweep(context, signal, blob, start_s)
            share = float(sweep.counted.mean())
            if share < self.options.max_risk or (best is not None and share <= best.share):
                continue
            first = np.where(sweep.inside[sweep.counted], np.arange(len(sweep.times)), len(sweep.times)).min(axis=1)
            k = int(first.min())
            best = Meeting(when_s=float(sweep.times[k]), driven_mm=float(sweep.driven[k]), blob=blob, share=share)
        return best

    def validate(self, signal: ControlSignal, context: ValidationContext) -> Verdict:
        checked_scan(context, self.name, self.options.expected_beams)
        if isinstance(signal, Turn):
            return Verdict(rule=self.name, valid=True, reason="a turn in place keeps the body where it is")
        if context.start_pose is None:
            return Verdict(rule=self.name, valid=True, reason="no pose: earlier scans cannot be compared")
        blobs, think = self.movers(context)
        if not blobs:
            return Verdict(rule=self.name, valid=True)
        start = self.start_s(context)
        meeting = self.first_meeting(context, signal, blobs, start)
        if meeting is None:
            return Verdict(rule=self.name, valid=True)
        return Verdict(rule=self.name, valid=False, reason=self._reason(signal, context, blobs, start, think, meeting))

    # -- the reason -----------------------------------------------------------------------------

    def _reason(self, signal: Straight, context: ValidationContext, blobs: list[Blob], start: float, think: float,
                meeting: Meeting) -> str:
        o = self.options
        blob = meeting.blob
        pose = context.planned_pose
        direction, _ = direction_words(signal)
        rad = math.radians(pose.heading_deg)
        c, s = math.cos(rad), math.sin(rad)

        def local(point: np.ndarray) -> tuple[float, float]:
            dx, dy = point[0] - pose.x_mm, point[1] - pose.y_mm
            x, y = dx * c + dy * s, -dx * s + dy * c
            return math.hypot(x, y), math.degrees(math.atan2(y, x))

        now_d, now_b = local(blob.centre)
        if blob.velocity is None:
            motion = f"velocity unknown (where it was not seen), taken as {o.unknown_speed_mm_s:g} mm/s any way"
        else:
            speed = float(np.hypot(*blob.velocity))
            course = math.degrees(math.atan2(blob.velocity[1], blob.velocity[0])) - pose.heading_deg
            motion = f"heading {(course + 180.0) % 360.0 - 180.0:.0f} deg at {speed:.0f} mm/s"
            turned = self.futures.turned_courses(blob)
            if turned:
                motion += (f"; slower than a mover cruising at {o.cruise_speed_mm_s:g} mm/s: it may have turned or "
                           f"stopped, {turned} of its courses go any way")
        safe = self._safe_distance(signal, context, blobs, start)
        if safe >= 1:
            advice = f"going {direction}, at most {safe} mm is safe"
        else:
            advice = (f"no {direction} motion is safe now (at most 0 mm is safe): wait for it to pass (turn in place "
                      f"a few degrees)")
        # the advice comes before the details: prompts cut long reasons (max_failure_chars)
        return (f"{signal.describe()}: a moving obstacle {now_d:.0f} mm away at {now_b:.0f} deg may be in the way; "
                f"{advice}. It moves ({motion}); {meeting.share:.0%} of its {o.futures} predicted courses meet this "
                f"motion, first {meeting.driven_mm:.0f} mm in, {meeting.when_s:.1f} s after the scan "
                f"(after {think:g} s think time)")

    def _safe_distance(self, signal: Straight, context: ValidationContext, blobs: list[Blob], start: float) -> int:
        """The longest straight in the same direction, in 10 mm steps, that meets no predicted mover."""
        best, low, high = 0, 1, int(signal.distance) - 1
        while low <= high:
            middle = (low + high) // 2
            shorter = Straight(command="straight", direction=signal.direction, distance=middle)
            if self.first_meeting(context, shorter, blobs, start) is None:
                best, low = middle, middle + 1
            else:
                high = middle - 1
        return best // 10 * 10
