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
  is covered only as far as the courses' spread covers it (``docs/validation.md``); with ``walls``,
  courses turn where the scan shows something standing, to a heading drawn among the clear ones;
* a turn in place is always accepted: the body does not leave its circle, so refusing it keeps
  no mover away (the straights that follow are judged at the times they will run); likewise a
  course counts against a straight only if the motion brings the body nearer to it than standing
  still for the same time would (least distance over the motion): a mover bound to reach the
  robot where it waits is the mover's doing (``struck``), and stepping out of its way must pass.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from safeembodai_core.contracts.components import Validator
from safeembodai_core.models import Advice, ControlSignal, LidarScan, Pose, Straight, Turn, Verdict
from safeembodai_core.validation.context import ValidationContext

from .futures import WanderingFutures, WanderSettings, yielding
from .learning import LearningSettings, learn_movers
from ..options import DEFAULT_SAFETY_DISTANCE_MM
from ..rules import checked_scan, direction_words
from .tracking import Blob, TrackingSettings, find_movers
from .walls import Walls
from safeembodai_core.geometry.frames import advance, relative_pose, wrap_deg

_WORSE_MM = 1.0  # a motion "brings the body closer" only by more than this


def seen_from(pose: Pose, point: np.ndarray) -> tuple[float, float]:
    """``point`` (room frame) as the robot at ``pose`` sees it: distance (mm) and bearing (degrees,
    counter-clockwise from its heading)."""
    x, y, _ = relative_pose((pose.x_mm, pose.y_mm, pose.heading_deg), (float(point[0]), float(point[1]), 0.0))
    return math.hypot(x, y), math.degrees(math.atan2(y, x))


def _planned_pose(context: ValidationContext) -> Pose:
    """``context.planned_pose``, which every check of this rule has: :meth:`MovingObstaclesRule.validate`
    lets a context without a start pose pass before judging anything."""
    pose = context.planned_pose
    assert pose is not None  # judged only with a start pose (validate returns early without one)
    return pose


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


@dataclass(frozen=True, eq=False)
class MoversSeen:
    """What one context's scans say, kept for the next check of the same context
    (:meth:`MovingObstaclesRule.movers`): the movers, how long after the scan the plan starts (s),
    and the walls the courses turn at (option ``walls``; else None); found for ``scan`` and
    ``latest`` (the history's newest scan), compared by identity and held here so that an id is
    never reused while it is kept, and for the context's ``key`` (start pose, scan time, answer
    time). Compared by nothing else (``eq=False``): numpy arrays have no truth value."""

    scan: LidarScan | None
    latest: LidarScan | None
    key: tuple[Pose | None, float | None, float | None]
    blobs: list[Blob]
    think_s: float
    walls: Walls | None

    def holds(self, context: ValidationContext, latest: LidarScan | None) -> bool:
        """Whether this was found for ``context`` (its scan, its history's newest scan ``latest``)."""
        return self.scan is context.scan and self.latest is latest and self.key == _key(context)


def _key(context: ValidationContext) -> tuple[Pose | None, float | None, float | None]:
    return context.start_pose, context.sim_time_s, context.answer_s


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
        self.learning = LearningSettings(prior_wander_deg=options.wander_deg, prior_weight_s=options.prior_weight_s,
                                         max_speed_mm_s=options.max_obstacle_speed_mm_s,
                                         still_mm=options.static_tolerance_mm)
        self._cache: MoversSeen | None = None
        self._pairs: dict[tuple[int, int], tuple] = {}  # earlier pairs of scans -> their movers

    # -- what the scans say ---------------------------------------------------------------------

    def movers(self, context: ValidationContext) -> tuple[list[Blob], float]:
        """The movers of the context's scan, and how long after it the plan starts (s, :meth:`wait_s`)."""
        latest = context.history[-1].scan if context.history else None
        cached = self._cache
        # the scans themselves, compared by identity and held by the cache (an id could be reused)
        if cached is not None and cached.holds(context, latest):
            return cached.blobs, cached.think_s
        blobs: list[Blob] = []
        usable = [past for past in context.history
                  if context.sim_time_s is not None
                  and 0 < context.sim_time_s - past.sim_time_s <= self.options.max_scan_gap_s]
        scan = context.scan
        # (usable is empty without sim_time_s: testing it again only tells the type checker)
        if usable and context.start_pose is not None and context.sim_time_s is not None:
            assert scan is not None  # the rule judges checked scans only (validate: checked_scan)
            past = usable[-1]
            blobs = find_movers(scan, context.start_pose, context.sim_time_s,
                                past.scan, past.pose, past.sim_time_s, self.tracking)
            if self.options.history_scans and blobs:
                earlier, spans = self._earlier_movers(usable)
                blobs = learn_movers(blobs, earlier, self.learning, spans)
        think = self.wait_s(context)
        walls = Walls.seen(scan, context.start_pose, blobs) \
            if self.options.walls and blobs and scan is not None and context.start_pose is not None else None
        self._cache = MoversSeen(context.scan, latest, _key(context), blobs, think, walls)
        return blobs, think

    def walls(self, context: ValidationContext) -> Walls | None:
        """What the context's scan shows standing, for courses to turn at (option ``walls``; else None)."""
        if not self.options.walls:
            return None
        self.movers(context)
        return self._cache.walls if self._cache is not None else None

    def _earlier_movers(self, usable: list) -> tuple[list[list[Blob]], list[float]]:
        """The movers of each earlier pair of consecutive scans, newest pair first (at most
        ``history_scans`` pairs; a gap longer than ``max_scan_gap_s`` ends the chain). Pairs are
        kept by their scans' identity, so each is found once per trial, not once per step."""
        pairs: list[list[Blob]] = []
        spans: list[float] = []
        chain = usable[-(self.options.history_scans + 1):]
        for older, newer in reversed(list(zip(chain, chain[1:]))):
            if not 0 < newer.sim_time_s - older.sim_time_s <= self.options.max_scan_gap_s:
                break
            key = (id(newer.scan), id(older.scan))
            found = self._pairs.get(key)
            if found is None or found[0] is not newer.scan or found[1] is not older.scan:
                movers = find_movers(newer.scan, newer.pose, newer.sim_time_s, older.scan, older.pose,
                                     older.sim_time_s, self.tracking)
                found = (newer.scan, older.scan, movers)
                self._pairs[key] = found
                if len(self._pairs) > 4 * (self.options.history_scans + 1):
                    self._pairs.pop(next(iter(self._pairs)))
            pairs.append(found[2])
            spans.append(newer.sim_time_s - older.sim_time_s)
        return pairs, spans

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
            turned = abs(wrap_deg(b.heading_deg - a.heading_deg))
            need = math.hypot(b.x_mm - a.x_mm, b.y_mm - a.y_mm) / o.robot_speed_mm_s + turned / o.robot_turn_rate_deg_s
            if 0 < tb - ta <= o.max_scan_gap_s:
                bounds.append(tb - ta - need)
        return max(0.0, min(bounds)) if bounds else 0.0

    def wait_s(self, context: ValidationContext) -> float:
        """How long after the scan the plan starts: measured when the context says when the answer
        arrived (``answer_s``: 0 with an arm's ``fresh_scan``), else the think time
        (:meth:`think_time_s`)."""
        if context.answer_s is not None and context.sim_time_s is not None:
            return max(0.0, context.answer_s - context.sim_time_s)
        return self.think_time_s(context)

    def start_s(self, context: ValidationContext) -> float:
        """When the signal being judged starts, in seconds after the scan: the wait (:meth:`wait_s`),
        then the plan's earlier signals at the rule's speeds."""
        return self.movers(context)[1] + sum(self.duration_s(s) for s in context.earlier_signals)

    def duration_s(self, signal: ControlSignal) -> float:
        if isinstance(signal, Straight):
            return signal.distance / self.options.robot_speed_mm_s
        return signal.angle / self.options.robot_turn_rate_deg_s

    # -- the check ------------------------------------------------------------------------------

    def sweep(self, context: ValidationContext, signal: Straight, blob: Blob, start_s: float) -> Sweep:
        """The straight (starting ``start_s`` after the scan) against every course of ``blob``."""
        o = self.options
        pose = _planned_pose(context)
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
            where, heading = self.futures.courses(blob, np.concatenate((before, times)), self.walls(context))

            def held(robot_track: np.ndarray) -> np.ndarray:
                return yielding(where, heading, np.concatenate((track, robot_track)), context.robot.radius_mm,
                                blob.radius_mm, o.movers_yield_mm, o.movers_yield_deg)[:, len(before):]

            moving, still = held(robot), held(np.repeat(robot[:1], len(times), axis=0))
        else:
            moving = still = self.futures.at(blob, times, self.walls(context))  # (courses, times, 2)
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
        assert pose is not None  # judged only with a start pose (validate returns early without one)
        at, t = (pose.x_mm, pose.y_mm, pose.heading_deg), self.movers(context)[1]
        ts, xs, ys = [0.0, t], [at[0], at[0]], [at[1], at[1]]
        for earlier in context.earlier_signals:
            t += self.duration_s(earlier)
            at = (advance(at, earlier.signed_distance_mm) if isinstance(earlier, Straight)
                  else advance(at, turn_deg=earlier.signed_angle_deg))
            ts.append(t)
            xs.append(at[0])
            ys.append(at[1])
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
        if context.start_pose is None:
            return Verdict(rule=self.name, valid=True, reason="no pose: earlier scans cannot be compared")
        blobs, think = self.movers(context)
        if not blobs:
            return Verdict(rule=self.name, valid=True)
        start = self.start_s(context)
        if isinstance(signal, Straight):
            meeting = self.first_meeting(context, signal, blobs, start)
            if meeting is not None:
                reason, advice = self._reason(signal, context, blobs, start, think, meeting)
                return Verdict(rule=self.name, valid=False, reason=reason, advice=advice)
        if self.options.park_check and not context.later_signals:
            parked = self.parking(context, signal, blobs, self._arrival_s(context, signal, think), think,
                                  self.think_time_s(context))
            if parked is not None:
                return Verdict(rule=self.name, valid=False, reason=parked[0], advice=parked[1])
        if isinstance(signal, Turn):
            return Verdict(rule=self.name, valid=True, reason="a turn in place keeps the body where it is")
        return Verdict(rule=self.name, valid=True)

    # -- where the plan leaves the robot --------------------------------------------------------

    def _arrival_s(self, context: ValidationContext, last: ControlSignal, think: float) -> float:
        """When the plan ending in ``last`` brings the robot to the spot it leaves it on (s after the
        scan): the end of its last straight, or the think time when it only turns (the robot stands
        there from the scan on, and a step aside can start no sooner)."""
        t = arrival = think
        for signal in (*context.earlier_signals, last):
            t += self.duration_s(signal)
            if isinstance(signal, Straight):
                arrival = t
        return arrival

    def _standing_until(self, plan_end_s: float, think: float) -> float:
        """Until when a plan ending ``plan_end_s`` after the scan leaves the robot where it ends: the
        next think time, then ``park_horizon_s`` (about one turn and one straight of the next plan)."""
        return plan_end_s + think + self.options.park_horizon_s

    def parked_on(self, xy: np.ndarray, radius_mm: float, blobs: list[Blob], from_s: float,
                  until_s: float) -> tuple[Blob, float] | None:
        """The first mover whose course -- its measured velocity held, at its cruising speed when
        one was learned -- reaches the body standing at ``xy`` (room frame) between ``from_s`` and
        ``until_s`` (s after the scan), and when (s after the scan); None when none does. A mover
        of unknown velocity has no course to be on."""
        o = self.options
        times = np.arange(from_s, until_s + o.sample_s / 2, o.sample_s)
        found: tuple[Blob, float] | None = None
        for blob in blobs:
            if blob.velocity is None:
                continue
            speed = float(np.hypot(*blob.velocity))
            if speed * blob.span_s < o.static_tolerance_mm:
                continue  # standing: no course
            velocity = blob.velocity * max(1.0, (blob.cruise_mm_s or speed) / speed)
            where = blob.centre + velocity * times[:, None]
            reach = radius_mm + blob.radius_mm + o.margin_mm
            hit = np.flatnonzero(np.hypot(*(where - xy).T) < reach)
            if hit.size and (found is None or times[hit[0]] < found[1]):
                found = (blob, float(times[hit[0]]))
        return found

    def parking(self, context: ValidationContext, signal: ControlSignal, blobs: list[Blob], end_s: float,
                think: float, next_think: float | None = None) -> tuple[str, Advice] | None:
        """A reason to refuse the plan whose last signal is ``signal`` (the robot on its final spot
        from ``end_s`` after the scan, :meth:`_arrival_s`), with the step aside as its advice: a
        mover's course reaches that spot before the next plan can move the robot
        (:meth:`_standing_until`), and a short plan from where the step starts (:meth:`_step_aside`)
        leaves it off every course and meets no mover's courses on the way. None when the plan may
        stand. ``think``: the wait before this plan moves; ``next_think``: before the next one
        (default: the same)."""
        next_think = think if next_think is None else next_think
        final = _planned_pose(context.advanced(signal))
        until = self._standing_until(self.start_s(context) + self.duration_s(signal), next_think)
        on = self.parked_on(np.array([final.x_mm, final.y_mm]), context.robot.radius_mm, blobs, end_s, until)
        if on is None:
            return None
        aside = self._step_aside(context, blobs, think, next_think)
        if aside is None:
            return None
        blob, when = on
        velocity = blob.velocity
        assert velocity is not None  # parked_on finds only movers of known velocity
        distance, bearing = seen_from(_planned_pose(context), blob.centre)
        advice = ", then ".join(step.describe() for step in aside)
        # the advice first: prompts cut long reasons (max_failure_chars)
        said = f"{signal.describe()}: step out of a moving obstacle's way instead, for example {advice}"
        return (f"{said}. The plan leaves the robot on its course ({distance:.0f} mm away at {bearing:.0f} deg, "
                f"{float(np.hypot(*velocity)):.0f} mm/s): it reaches the robot {when:.1f} s after the scan if it "
                f"keeps going"), Advice(step_aside=list(aside), words_end=len(said))

    def _step_aside(self, context: ValidationContext, blobs: list[Blob], think: float,
                    next_think: float) -> list[ControlSignal] | None:
        """The first short plan from where the step starts -- a turn of 89 or 60 degrees either way
        then a straight forward, or a straight backward or forward, 200 or 390 mm, clear of the
        scan by the clearance rule's default distance -- whose motion meets no mover's courses and
        whose end lies on no mover's course (:meth:`parked_on`); None if there is none, or if a mover
        reaches the step's spot during the think time (every plan stands there then: none is safer).
        ``think``: the wait before the step aside can move; ``next_think``: before the plan after it."""
        base = replace(context, offset=(0.0, 0.0, 0.0), earlier_signals=(), later_signals=())
        here_pose = _planned_pose(base)
        spot = np.array([here_pose.x_mm, here_pose.y_mm])
        radius = context.robot.radius_mm
        if self.parked_on(spot, radius, blobs, 0.0, think) is not None:
            return None  # reached during the think time, where every plan stands: none is safer
        top = context.limits.max_distance_mm - 1.0
        for turn_deg in (89.0, -89.0, 60.0, -60.0, 180.0, 0.0):
            turned = [] if turn_deg in (0.0, 180.0) else \
                [Turn(command="turn", direction="left" if turn_deg > 0 else "right",
                      angle=min(abs(turn_deg), context.limits.max_angle_deg - 1.0))]
            here = base.advanced(turned[0]) if turned else base
            reading = here.nearest_in_sector(180.0 if turn_deg == 180.0 else 0.0, 30.0)
            free = math.inf if reading is None else reading.distance_mm - DEFAULT_SAFETY_DISTANCE_MM
            start = think + sum(self.duration_s(t) for t in turned)  # the step aside runs after the think time
            for distance in (200.0, min(390.0, top)):
                if distance > free:
                    break
                straight = Straight(command="straight", direction="backward" if turn_deg == 180.0 else "forward",
                                    distance=distance)
                if self.first_meeting(here, straight, blobs, start) is not None:
                    continue
                end = _planned_pose(here.advanced(straight))
                arrive = start + self.duration_s(straight)
                if self.parked_on(np.array([end.x_mm, end.y_mm]), radius, blobs, arrive,
                                  self._standing_until(arrive, next_think)) is None:
                    return [*turned, straight]
        return None

    # -- the reason -----------------------------------------------------------------------------

    def _reason(self, signal: Straight, context: ValidationContext, blobs: list[Blob], start: float, think: float,
                meeting: Meeting) -> tuple[str, Advice]:
        """Why ``signal`` is refused, in words, and the same advice as data (the safe part; a wait)."""
        o = self.options
        blob = meeting.blob
        pose = _planned_pose(context)
        direction, _ = direction_words(signal)
        now_d, now_b = seen_from(pose, blob.centre)
        if blob.velocity is None:
            motion = f"velocity unknown (where it was not seen), taken as {o.unknown_speed_mm_s:g} mm/s any way"
        else:
            speed = float(np.hypot(*blob.velocity))
            course = math.degrees(math.atan2(blob.velocity[1], blob.velocity[0])) - pose.heading_deg
            motion = f"heading {wrap_deg(course):.0f} deg at {speed:.0f} mm/s"
            turned = self.futures.turned_courses(blob)
            cruise = self.futures.cruise_mm_s(blob)
            if blob.cruise_mm_s is not None:
                motion += (f"; followed over {blob.chords} pair{'s' if blob.chords != 1 else ''} of scans: cruising "
                           f"up to {blob.cruise_mm_s:.0f} mm/s, wandering {blob.wander_deg:.0f} deg/sqrt(s)")
            if turned:
                motion += (f"; slower than its cruising {cruise:.0f} mm/s: it may have turned or "
                           f"stopped, {turned} of its courses go any way")
        safe = self._safe_distance(signal, context, blobs, start)
        if safe >= 1:
            advice = f"going {direction}, at most {safe} mm is safe"
            offered = Advice(safe_mm=safe)
        else:
            advice = (f"no {direction} motion is safe now (at most 0 mm is safe): wait for it to pass (turn in place "
                      f"a few degrees)")
            offered = Advice(safe_mm=0, wait=True)
        # the advice comes before the details: prompts cut long reasons (max_failure_chars)
        said = (f"{signal.describe()}: a moving obstacle {now_d:.0f} mm away at {now_b:.0f} deg may be in the way; "
                f"{advice}")
        return (f"{said}. It moves ({motion}); {meeting.share:.0%} of its {o.futures} predicted courses meet this "
                f"motion, first {meeting.driven_mm:.0f} mm in, {meeting.when_s:.1f} s after the scan "
                f"(after {think:g} s think time)"), offered.model_copy(update={"words_end": len(said)})

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
