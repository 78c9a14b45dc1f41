"""``moving_obstacles`` on synthetic scans: a square room with discs, scanned twice.

A mover on a known straight course is found and predicted; a plan crossing its predicted path is
refused with advice that passes when followed, a plan away from it is accepted; a static scene
refuses nothing; a return seen once is assumed static. The property test drives the robot with
random plans towards a mover on a random straight course and checks, with the rule's own motion
model, that every plan whose motion drives the body into the mover is refused."""

from __future__ import annotations

import functools
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

from safeembodai_core.models import Pose, Straight, Turn
from safeembodai_core.validation.context import PastScan, ValidationContext, validate_plan
from safeembodai_plugins.validators import MovingObstaclesOptions
from safeembodai_plugins.validators.moving import MovingObstaclesRule

from mover_scenes import LABBOT_MM, ROBOT, ROOM_MM, THINK_S, go, rotate, scan_from

BALL_MM = 110.0


def context_for(pose: Pose, now, before=None, before_pose: Pose | None = None, dt_s: float = 5.0) -> ValidationContext:
    """The step's scan sees discs ``now``; the trial's previous scan, ``dt_s`` earlier, saw
    ``before`` from ``before_pose`` (default: the same pose); no previous scan if ``before`` is None."""
    history = () if before is None else (PastScan(scan_from(before_pose or pose, before), before_pose or pose, 10.0),)
    return ValidationContext(scan=scan_from(pose, now), start_pose=pose, sim_time_s=10.0 + dt_s, history=history)


def rule(**options) -> MovingObstaclesRule:
    return MovingObstaclesRule(MovingObstaclesOptions(**{"think_time_s": THINK_S, **options}))


def refusals(plan, context, validator=None):
    verdicts = validate_plan(plan, context, [("moving_obstacles", validator or rule())])
    return [v for v in verdicts if not v.valid]


BALL = (4500.0, 1500.0, BALL_MM)
# a Labbot crossing 2 m ahead from left to right at 150 mm/s (750 mm further on than 5 s ago), due
# to cross the robot's line 13.5 s after the scan
CROSSING = {"before": [(3000.0, 5775.0, LABBOT_MM), BALL], "now": [(3000.0, 5025.0, LABBOT_MM), BALL]}


def test_a_mover_is_found_with_its_velocity():
    context = context_for(ROBOT, CROSSING["now"], CROSSING["before"])
    blobs, think = rule().movers(context)
    assert think == THINK_S and len(blobs) == 1  # the ball and the walls cancel out
    assert np.allclose(blobs[0].centre, (3000.0, 5025.0), atol=30.0)
    assert np.allclose(blobs[0].velocity, (0.0, -150.0), atol=10.0)
    assert abs(blobs[0].radius_mm - LABBOT_MM) < 30.0


def test_a_plan_crossing_its_predicted_path_is_refused_and_the_advice_passes():
    context = context_for(ROBOT, CROSSING["now"], CROSSING["before"])
    plan = [go(399)] * 5  # reaches x = 3000 when the Labbot is there
    refused = refusals(plan, context)
    assert refused and refused[0].signal_index >= 1
    reason = refused[0].reason
    assert "a moving obstacle" in reason and "may be in the way" in reason and "think time" in reason
    assert -95 < float(reason.split("heading ")[1].split(" deg")[0]) < -85  # to the robot's right
    assert reason.index("at most") < 200  # the advice survives the prompt's cut of long reasons
    safe = int(reason.split("at most ")[1].split(" mm")[0])
    shorter = plan[:refused[0].signal_index] + ([go(safe)] if safe >= 1 else [])
    assert not refusals(shorter, context)


def test_a_plan_away_from_it_is_accepted():
    context = context_for(ROBOT, CROSSING["now"], CROSSING["before"])
    assert not refusals([go(-399), go(-399)], context)  # backward, away from its path
    assert not refusals([rotate(-89), go(399), go(399)], context)  # to the right, out of its way soon enough
    assert not refusals([go(399)], context)  # one straight is over before it gets there


def test_a_static_scene_refuses_nothing():
    scene = [BALL, (2500.0, 2500.0, LABBOT_MM), (1500.0, 4200.0, 200.0)]
    moved = Pose(x_mm=800.0, y_mm=2700.0, heading_deg=35.0)  # the robot moved between the scans
    for before_pose in (ROBOT, moved):
        context = context_for(ROBOT, scene, scene, before_pose=before_pose)
        assert rule().movers(context)[0] == []
        for angle in range(-180, 180, 30):
            plan = [rotate(angle / 3)] * 3 if angle else []
            assert not refusals(plan + [go(399), go(399), go(399)], context)


def test_a_return_seen_once_is_assumed_static():
    """Step 1 (no earlier scan): nothing is known to move, so nothing is refused, even a straight
    at a Labbot; other rules judge where things are. The verdict says nothing of motion."""
    context = context_for(ROBOT, [(1500.0, 3000.0, LABBOT_MM)])
    verdict = rule().validate(go(399), context)
    assert verdict.valid and verdict.reason == ""


def test_a_mover_out_of_a_shadow_has_unknown_velocity():
    """The Labbot now stands where the earlier scan saw free space, but where it was then was
    hidden behind a pillar: no velocity; it may move ``unknown_speed_mm_s`` any way."""
    pillar = (2000.0, 3600.0, 250.0)
    before = [pillar, (3000.0, 4600.0, LABBOT_MM)]  # hidden behind the pillar, seen from ROBOT
    now = [pillar, (2300.0, 2600.0, LABBOT_MM)]
    context = context_for(ROBOT, now, before)
    blobs, _ = rule().movers(context)
    assert len(blobs) == 1 and blobs[0].velocity is None
    refused = refusals([go(399), go(399), go(399)], context, rule(unknown_speed_mm_s=100))
    assert refused and "velocity unknown" in refused[0].reason
    assert not refusals([go(399), go(399), go(399)], context, rule(unknown_speed_mm_s=0, margin_growth_mm_s=0))


def test_the_think_time_is_estimated_from_the_observation_times():
    """Unset, the think time is the least (time between observations - time the pose change
    needs): exact after a step whose answers were all refused (the robot did not move)."""
    scan = scan_from(ROBOT, [])
    moved = Pose(x_mm=1400.0, y_mm=3000.0, heading_deg=0.0)
    history = (PastScan(scan, ROBOT, 0.0), PastScan(scan, moved, 8.0))  # 400 mm in 2 s + 6 s thinking
    context = ValidationContext(scan=scan, start_pose=moved, sim_time_s=13.0, history=history)  # 5 s, no motion
    assert MovingObstaclesRule(MovingObstaclesOptions()).think_time_s(context) == pytest.approx(5.0)
    assert MovingObstaclesRule(MovingObstaclesOptions(think_time_s=2)).think_time_s(context) == 2.0


def test_a_turn_is_always_accepted_and_no_pose_accepts():
    context = context_for(ROBOT, CROSSING["now"], CROSSING["before"])
    assert rule().validate(rotate(45), context).valid
    blind = ValidationContext(scan=context.scan, history=context.history, sim_time_s=15.0)
    assert rule().validate(go(399), blind).valid


# -- the property: every plan that drives the robot into the mover is refused ----------------------

#: What the oracle leaves to the rule beyond its reading's error E: a straight that comes more than d
#: inside the mover where standing still stays d clear comes 2 d nearer than standing; on the rule's
#: reading each least distance moves by at most E, so the rule sees at least 2 (d - E) nearer, which
#: with d = E + 2 mm beats the rule's 1 mm (``_WORSE_MM``) and its sampling every 0.1 s (under 1 mm
#: here). A number of the test's own: were it read from the rule, a rule that stopped refusing by
#: raising its threshold would raise the oracle's with it.
_SLACK_MM = 2.0


def _estimate_error_mm(estimate: tuple[np.ndarray, np.ndarray], centre: np.ndarray, velocity: np.ndarray,
                       start_s: float, end_s: float) -> float:
    """How far the course the rule read from the scans (``estimate``: centre now, velocity) lies
    from the mover's true course at most between ``start_s`` and ``end_s`` after the scan (the
    error is linear in time, so largest at one end)."""
    off, drift = estimate[0] - centre, estimate[1] - velocity
    return max(float(np.hypot(*(off + drift * start_s))), float(np.hypot(*(off + drift * end_s))))


def _meets_by_its_own_motion(plan, pose: Pose, centre: np.ndarray, velocity: np.ndarray, radius: float,
                             options: MovingObstaclesOptions, depth_mm: float = 0.0,
                             estimate: tuple[np.ndarray, np.ndarray] | None = None) -> bool:
    """Under the rule's timing (think time, then the signals at the rule's speeds; the mover on
    its straight course): does some straight drive the body more than ``depth_mm`` into the mover,
    where standing still at its start for the same time would have stayed ``depth_mm`` clear of it?
    Given the rule's ``estimate`` of the mover (centre now, velocity), the depth of each straight is
    at least how far that estimate is off the true course during it, plus ``_SLACK_MM``: a meeting
    shallower than the estimate's error is one the scans cannot tell from a miss."""
    x, y, heading, t = pose.x_mm, pose.y_mm, pose.heading_deg, THINK_S
    for signal in plan:
        if isinstance(signal, Turn):
            heading += signal.signed_angle_deg
            t += signal.angle / options.robot_turn_rate_deg_s
            continue
        duration = signal.distance / options.robot_speed_mm_s
        depth = depth_mm if estimate is None else \
            max(depth_mm, _estimate_error_mm(estimate, centre, velocity, t, t + duration) + _SLACK_MM)
        reach = 170.0 + radius - depth
        clear = 170.0 + radius + depth
        times = t + np.linspace(0.0, duration, 400)
        rad = math.radians(heading)
        step = signal.signed_distance_mm * (times - t) / duration
        body = np.column_stack((x + step * math.cos(rad), y + step * math.sin(rad)))
        mover = centre + times[:, None] * velocity
        standing = np.hypot(x - mover[:, 0], y - mover[:, 1])
        if np.hypot(*(body - mover).T).min() < reach and clear <= standing.min():
            return True
        x, y, t = (x + signal.signed_distance_mm * math.cos(rad), y + signal.signed_distance_mm * math.sin(rad),
                   t + duration)
    return False


def _body_at(plan, pose: Pose, when: float, options: MovingObstaclesOptions) -> np.ndarray:
    """Where the rule's motion model puts the robot's centre ``when`` seconds after the scan."""
    x, y, heading, t = pose.x_mm, pose.y_mm, pose.heading_deg, THINK_S
    for signal in plan:
        straight = isinstance(signal, Straight)
        duration = (signal.distance / options.robot_speed_mm_s if straight
                    else signal.angle / options.robot_turn_rate_deg_s)
        share = min(max((when - t) / duration, 0.0), 1.0)
        if straight:
            rad = math.radians(heading)
            x, y = (x + share * signal.signed_distance_mm * math.cos(rad),
                    y + share * signal.signed_distance_mm * math.sin(rad))
        else:
            heading += share * signal.signed_angle_deg
        t += duration
    return np.array([x, y])


@functools.cache
def _shipped(path: str = "scenarios/dynamic.yaml", arm: str = "told") -> dict:
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    root = Path(__file__).resolve().parents[4]
    scenario = load_scenario(str(root / path), [], load_plugins(environ={}).registry)
    ref = next(v for v in scenario.arms[arm].validators if getattr(v, "use", v) == "moving_obstacles")
    return dict(ref.options)


def _shipped_options(yielding: bool) -> dict:
    """The ``told`` arm's options in ``scenarios/dynamic.yaml`` (the rule told the Labbots' cruising
    speed and yielding; its ``moving`` arm until issue 39), without its yielding movers if asked."""
    options = dict(_shipped())
    if not yielding:
        options.pop("movers_yield_mm", None)
    return options


def _crossing(plan, heading: float, share: float, speed: float, course: float, offset: float, side: float,
              options: MovingObstaclesOptions) -> tuple[Pose, np.ndarray, np.ndarray, np.ndarray]:
    """The property's scene: the robot at the room's centre facing ``heading``; a mover at ``speed``
    on ``course`` passing ``offset`` mm from the robot (towards ``side``) at the moment ``share`` of
    the plan's execution. The robot's pose, the mover's centre at the scan and 5 s before, its velocity."""
    pose = Pose(x_mm=3000.0, y_mm=3000.0, heading_deg=heading)
    total = sum(s.distance / 200.0 if isinstance(s, Straight) else s.angle / 60.0 for s in plan)
    when = THINK_S + share * total
    rad, aside = math.radians(course), math.radians(side)
    velocity = speed * np.array([math.cos(rad), math.sin(rad)])
    meet = _body_at(plan, pose, when, options) + offset * np.array([math.cos(aside), math.sin(aside)])
    now = meet - when * velocity
    return pose, now, now - 5.0 * velocity, velocity


def _read_by_the_rule(validator: MovingObstaclesRule, context: ValidationContext,
                      near: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """The rule's reading of the mover near ``near`` (its centre now, its velocity), None when the
    rule found none there with a velocity (the oracle then demands the exact truth)."""
    read = [blob for blob in validator.movers(context)[0] if blob.velocity is not None]
    if not read:
        return None
    blob = min(read, key=lambda b: float(np.hypot(*(b.centre - near))))
    assert blob.velocity is not None
    return blob.centre, blob.velocity


signals = st.one_of(
    st.builds(go, st.floats(1, 399).flatmap(lambda d: st.sampled_from([d, -d]))),
    st.builds(rotate, st.floats(1, 89).flatmap(lambda a: st.sampled_from([a, -a]))),
)


@settings(max_examples=200, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(plan=st.lists(signals, min_size=1, max_size=5), heading=st.floats(-180, 180), share=st.floats(0, 1),
       speed=st.floats(80, 250), course=st.floats(-180, 180), offset=st.floats(0, 400), side=st.floats(-180, 180))
# a Labbot coming from behind along the line of sight while the robot backs into it (it hides where
# it was: found by this test once), and one crossing ahead of three straights
@example(plan=[go(-290.0)], heading=0.0, share=1.0, speed=138.0, course=0.0, offset=0.0, side=0.0)
@example(plan=[go(399.0)] * 3, heading=0.0, share=0.6, speed=150.0, course=-90.0, offset=0.0, side=0.0)
# a fast mover from behind on the robot's left that backing away grazes while it nearly reaches the
# waiting robot anyway: few of its wandering courses count (found by this test in CI)
@example(plan=[go(-180.0)], heading=0.0, share=0.34375, speed=181.0, course=-151.0, offset=213.0, side=99.0)
# a straight course that a 149 mm straight (after one of 1 mm) grazes 7 mm deep where waiting would
# leave the robot 5 mm clear; the scans read the mover 5 mm/s fast, 35 to 39 mm off the truth by
# then, reaching the waiting robot anyway: no reading of these scans tells this from a miss (found
# by this test); split or not: one straight of 160 mm, the mover 3 mm further off, grazes it the same
@example(plan=[go(1.0), go(149.0), go(296.0), rotate(9.0)], heading=107.625, share=0.30078125, speed=81.0,
         course=-98.25, offset=283.0, side=9.0)
@example(plan=[go(160.0), go(296.0), rotate(9.0)], heading=107.625, share=0.30078125, speed=81.0,
         course=-98.25, offset=286.0, side=9.0)
@pytest.mark.parametrize("wander, cruising", [(0.0, False), (25.0, False), (25.0, True)],
                         ids=["straight-courses", "wandering-courses", "cruising-courses"])
@pytest.mark.slow
def test_every_plan_that_drives_into_the_mover_is_refused(wander, cruising, plan, heading, share, speed, course, offset,
                                                          side):
    """The mover, on a straight course at a constant speed, is placed to pass within ``offset`` of
    where the plan puts the robot at a moment drawn from its execution; the robot starts at the
    room's centre. With straight courses (``wander_deg`` 0) every plan whose own motion drives the
    body into it, where standing still would have stayed clear of it, is refused, both by more than
    the rule's reading of the mover from the two scans is off its true course then (a few mm, and a
    few mm/s: tens of mm after the think time) -- within that the scans cannot tell a graze from a
    miss, nor a mover that would reach the waiting robot anyway (the rule's "nearer than standing
    still") from one that would not; with wandering courses (the default) every plan that drives
    the body into its straight course by more than 60 mm, where standing still would have stayed
    60 mm clear of it, is refused too (there the straight course is one of many, and a graze of it
    -- or a course that nearly reaches the waiting robot anyway -- can count in fewer than
    ``max_risk`` of them). With the options of ``scenarios/dynamic.yaml``'s ``told`` arm (cruising speed 150
    mm/s, its margin growth and ``max_risk``; these movers do not yield) the same holds for a mover
    at least that fast."""
    if cruising:
        speed = 150.0 + (speed - 80.0) * 100.0 / 170.0  # 150 to 250 mm/s: at least the cruising speed
        validator = rule(**_shipped_options(yielding=False))
    else:
        validator = rule(wander_deg=wander, cruise_speed_mm_s=None)  # courses at the measured speed
    pose, now, before, velocity = _crossing(plan, heading, share, speed, course, offset, side, validator.options)
    for point in (now, before):
        if np.hypot(*(point - 3000.0)) < 700 or not ((350 < point) & (point < ROOM_MM - 350)).all():
            return  # the mover is read clear of the robot and of the walls
    context = context_for(pose, [(*now, LABBOT_MM)], [(*before, LABBOT_MM)])
    meets = _meets_by_its_own_motion(plan, pose, now, velocity, LABBOT_MM, validator.options,
                                     depth_mm=60.0 if wander else 0.0,
                                     estimate=None if wander else _read_by_the_rule(validator, context, now))
    event("meets" if meets else "does not meet")  # `pytest --hypothesis-show-statistics`: about 1 in 10 meets
    if meets:
        assert refusals(plan, context, validator), [s.describe() for s in plan]


def test_a_graze_shallower_than_the_scans_error_is_not_demanded_split_or_not():
    """The property's counterexample, a straight split in pieces of 1 and 149 mm (the second grazes
    the mover 7 mm deep where waiting would leave the robot 5 mm clear): told the mover's true
    course, the rule refuses the 149 mm piece and the unsplit 150 mm straight alike (a split hides
    little: a piece comes at most its own length nearer than standing still, so only a piece of 1 mm
    or less -- under ``_WORSE_MM`` -- is never counted). Read from the scans, the mover is 5 mm/s
    fast and about 38 mm off by then, farther than the graze is deep: the oracle does not demand
    that refusal. Deeper than the reading's error, it does, and the rule refuses the split plan."""
    from safeembodai_plugins.validators.moving.tracking import Blob

    split = [go(1.0), go(149.0), go(296.0), rotate(9.0)]
    validator = rule(wander_deg=0.0, cruise_speed_mm_s=None)
    pose, now, before, velocity = _crossing(split, 107.625, 0.30078125, 81.0, -98.25, 283.0, 9.0, validator.options)
    context = context_for(pose, [(*now, LABBOT_MM)], [(*before, LABBOT_MM)])
    assert _meets_by_its_own_motion(split, pose, now, velocity, LABBOT_MM, validator.options)  # the truth
    read = _read_by_the_rule(validator, context, now)
    assert read is not None
    assert not _meets_by_its_own_motion(split, pose, now, velocity, LABBOT_MM, validator.options, estimate=read)
    true = [Blob(centre=now, radius_mm=LABBOT_MM, velocity=velocity, points=10, span_s=5.0)]
    after_1mm = context.advanced(split[0])
    assert validator.first_meeting(after_1mm, split[1], true, validator.start_s(after_1mm)) is not None
    assert validator.first_meeting(context, go(150.0), true, THINK_S) is not None  # the same, unsplit
    assert validator.first_meeting(context, split[0], true, THINK_S) is None  # 1 mm comes 1 mm nearer at most
    # the mover passing 200 mm off, on the robot's left: deeper than the reading's error, and the rule
    # on its own reading refuses the split plan's 149 mm piece
    deeper = _crossing(split, 107.625, 0.30078125, 81.0, -98.25, 200.0, 90.0, validator.options)
    context = context_for(deeper[0], [(*deeper[1], LABBOT_MM)], [(*deeper[2], LABBOT_MM)])
    read = _read_by_the_rule(validator, context, deeper[1])
    assert _meets_by_its_own_motion(split, deeper[0], deeper[1], deeper[3], LABBOT_MM, validator.options,
                                    estimate=read)
    assert [refused.signal_index for refused in refusals(split, context, validator)][:1] == [1]


def test_a_guard_given_times_keeps_its_scans_for_moving_obstacles():
    """A library user's ``Guard``: checks with ``pose`` and ``time_s`` keep their scans, so the
    second check sees the Labbot move and refuses the plan that crosses its course; without times
    (or with the same reading re-checked) there is nothing to compare and the plan passes."""
    from safeembodai_core import Guard

    rules = ["command_limits", {"use": "moving_obstacles", "options": {"think_time_s": THINK_S}}]
    plan = [{"command": "straight", "direction": "forward", "distance": 399}] * 5
    before, now = scan_from(ROBOT, CROSSING["before"]), scan_from(ROBOT, CROSSING["now"])
    guard = Guard(rules)
    assert guard.check(plan[:1], lidar_mm=before, pose=ROBOT, time_s=10.0).valid
    refused = guard.check(plan, lidar_mm=now, pose=ROBOT, time_s=15.0)
    assert not refused.valid and "moving_obstacles" in {v.rule for v in refused.verdicts if not v.valid}
    assert len(guard.history) == 2
    assert not guard.check(plan, lidar_mm=now, pose=ROBOT, time_s=15.0).valid  # same reading: same verdict
    assert len(guard.history) == 2
    untimed = Guard(rules)
    untimed.check(plan[:1], lidar_mm=before, pose=ROBOT)
    assert untimed.check(plan, lidar_mm=now, pose=ROBOT).valid and not untimed.history
    with pytest.raises(ValueError, match="time_s"):
        Guard(rules).check(plan, lidar_mm=now, pose=ROBOT, time_s=float("nan"))


def test_a_guard_copes_with_a_refilled_buffer_a_clock_reset_and_refuses_a_time_as_text():
    """Scans are copied when kept (a driver refilling one buffer must not rewrite them); a time
    earlier than the last kept one starts a new history; a time is a number of seconds, never text
    (issue 52 item 14: ``"10"`` was read as 10 s once; no number the guard reads comes as text)."""
    from safeembodai_core import Guard

    rules = ["command_limits", {"use": "moving_obstacles", "options": {"think_time_s": THINK_S}}]
    plan = [{"command": "straight", "direction": "forward", "distance": 399}] * 5
    before, now = scan_from(ROBOT, CROSSING["before"]), scan_from(ROBOT, CROSSING["now"])
    guard, buffer = Guard(rules), np.empty(before.beam_count)
    buffer[:] = before.ranges_mm
    with pytest.raises(ValueError, match="time_s must be a number of seconds, got '10'"):
        guard.check(plan[:1], lidar_mm=buffer, max_range_mm=before.max_range_mm, pose=ROBOT, time_s="10")
    guard.check(plan[:1], lidar_mm=buffer, max_range_mm=before.max_range_mm, pose=ROBOT, time_s=10)
    buffer[:] = now.ranges_mm
    assert not guard.check(plan, lidar_mm=buffer, max_range_mm=now.max_range_mm, pose=ROBOT, time_s=15).valid
    assert guard.history[0].scan.ranges_mm is not buffer and not guard.history[0].scan.ranges_mm.flags.writeable
    # a new episode whose clock starts again: the old scans are dropped, nothing to compare
    assert guard.check(plan, lidar_mm=now, pose=ROBOT, time_s=2.0).valid and len(guard.history) == 1
    with pytest.raises(ValueError, match="time_s must be a number"):
        guard.check(plan, lidar_mm=now, pose=ROBOT, time_s="soon")


def test_an_earlier_scan_too_old_to_say_anything_is_not_compared():
    """Scans more than ``max_scan_gap_s`` apart give no mover (and the check stays cheap)."""
    context = context_for(ROBOT, CROSSING["now"], CROSSING["before"], dt_s=300.0)
    assert rule().movers(context)[0] == []
    assert not refusals([go(399)] * 5, context, rule(think_time_s=None))
    assert rule(max_scan_gap_s=600.0).movers(context)[0]  # told the scans still count: the mover is found


def test_what_a_context_s_scans_say_is_kept_by_name_and_found_again_only_for_that_context():
    from dataclasses import replace

    from safeembodai_plugins.validators.moving import MoversSeen

    mover = rule(walls=True)
    context = context_for(ROBOT, CROSSING["now"], CROSSING["before"])
    blobs, think = mover.movers(context)
    seen = mover._cache
    assert isinstance(seen, MoversSeen) and seen.blobs is blobs and seen.think_s == think
    assert seen.scan is context.scan and seen.latest is context.history[-1].scan
    assert seen.key == (context.start_pose, context.sim_time_s, context.answer_s)
    assert mover.walls(context) is seen.walls is not None  # the walls option: found with the movers
    assert mover.movers(context)[0] is blobs and mover._cache is seen  # the same context: not found again
    later = replace(context, answer_s=context.sim_time_s + 1.0)  # another key: found again, waiting 1 s
    assert mover.movers(later)[1] == 1.0 and mover._cache is not seen
    copied = replace(context, scan=scan_from(ROBOT, CROSSING["now"]))  # an equal scan, another object
    assert mover.movers(copied)[0] is not blobs
