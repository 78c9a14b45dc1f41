"""A motion judged on the robot's own scan: the plan as the base drives it, refusals with their numbers, limits."""

from __future__ import annotations

import math

import pytest

from safeembodai_core import Guard
from safeembodai_core.guard_mcp.calls import Hold, Motion
from safeembodai_core.guard_mcp.judging import MotionJudge, Step, after
from safeembodai_core.guard_mcp.policy import read_policy
from safeembodai_core.guard_mcp.senses import RobotSenses
from safeembodai_core.ros.robot_file import RobotFile
from safeembodai_core.ros.twist import Twist

ROBOT = RobotFile(radius_mm=170.0, scans={"/scan": {"null_range": "no_return"}})
REACH_MM = 170.0 + 50.0  # the body and the margin


def judge_for(mode="refuse", robot=ROBOT, **changes):
    policy = read_policy().model_copy(update={"mode": mode, **changes})
    guard = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": policy.margin_mm}}],
                  robot=robot.robot_spec())
    return MotionJudge(guard, robot, policy)


def view_of(ranges, scans):
    senses = RobotSenses(ROBOT, scan_timeout_s=0.5, odom_topic=None, clock=lambda: 0.0)
    senses.on_scan(scans.message(ranges), 0.0)
    return senses.view(0.0)


def motion(*holds, kind="publish_for_durations"):
    return Motion("t", kind, "/cmd_vel", "geometry_msgs/msg/Twist",
                  tuple(Hold(Twist(x, z), seconds, {}) for x, z, seconds in holds))


def test_the_plan_holds_a_single_publish_for_the_horizon_and_the_last_moving_message_for_more():
    judge = judge_for(horizon_s=0.4)  # shorter than the base's 0.5 s timeout: the timeout wins
    assert [(s.twist.linear_x, s.seconds) for s in judge.plan(motion((0.2, 0, 0.0), kind="publish_once"))] == [
        (0.2, 0.5)]
    plan = judge.plan(motion((0.2, 0, 1.5)))
    assert [(s.seconds, s.tail) for s in plan] == [(1.5, False), (0.5, True)]
    assert [s.seconds for s in judge.plan(motion((0.2, 0, 1.5), (0.0, 0, 0.3)))] == [1.5, 0.3]


def test_what_is_ahead_is_the_rest_of_the_plan_over_the_window():
    judge = judge_for()  # window: max(1.0, 0.2 + 0.5)
    plan = [Step(Twist(0.2, 0.0), 0.5, "a", 0), Step(Twist(0.0, 0.5), 2.0, "b", 1)]
    assert [(s.what, round(s.seconds, 3)) for s in judge.ahead(plan, 0.3)] == [("a", 0.2), ("b", 0.8)]
    assert judge.ahead(plan, 2.6) == []


def test_a_drive_short_of_the_wall_passes_and_one_into_it_says_how_far_is_safe(scans):
    judge, view = judge_for(), view_of(scans.wall_at(1.0), scans)
    assert judge.judge(judge.plan(motion((0.2, 0, 1.0), (0.0, 0, 0.0))), view).ok
    refused = judge.judge(judge.plan(motion((0.2, 0, 5.0), (0.0, 0, 0.0))), view)
    assert not refused.ok and refused.safe["message"] == 0
    assert refused.safe["at_most_mm"] == pytest.approx(1000.0 - REACH_MM, abs=10.0)
    assert refused.safe["slow_to_m_s"] == pytest.approx(0.2 * refused.safe["safe_duration_s"] / 5.0, abs=1e-3)
    assert any("at most" in line and "mm" in line for line in refused.advice)
    assert any("swept_body" in line for line in refused.reasons)


def test_the_bases_hold_after_the_last_message_is_judged_and_a_closing_stop_is_advised(scans):
    judge, view = judge_for(), view_of(scans.wall_at(1.0), scans)
    refused = judge.judge(judge.plan(motion((0.2, 0, 3.0))), view)  # 600 mm, then 200 mm more held
    assert not refused.ok and refused.safe["after_the_last_message"] and "end with a stop" in refused.advice[0]
    assert judge.judge(judge.plan(motion((0.2, 0, 3.0), (0.0, 0, 0.0))), view).ok


def test_each_message_is_judged_from_where_the_ones_before_leave_the_robot(scans):
    judge, view = judge_for(), view_of(scans.wall_at(1.0), scans)
    turn_then_drive = motion((0.0, math.pi / 4, 2.0), (0.3, 0, 3.0), (0.0, 0, 0.0))  # a quarter turn left, away
    assert judge.judge(judge.plan(turn_then_drive), view).ok
    drive_then_turn = motion((0.3, 0, 3.0), (0.0, math.pi / 4, 2.0), (0.0, 0, 0.0))
    assert not judge.judge(judge.plan(drive_then_turn), view).ok
    assert after((0.0, 0.0, 0.0), Twist(0.0, math.pi / 4), 2.0) == pytest.approx((0.0, 0.0, 90.0))


@pytest.mark.parametrize("speed", [2.0, 1e300, -3.0])
def test_a_speed_beyond_the_robot_files_limits_is_refused_with_the_speed_that_would_do(speed, scans):
    judge, view = judge_for(), view_of(scans.open(), scans)
    refused = judge.judge(judge.plan(motion((speed, 0, 0.1), kind="publish_once")), view)
    assert not refused.ok and "velocity" in refused.reasons[1]
    assert refused.safe["slow_to_m_s"] == pytest.approx(0.5 if speed > 0 else -0.5)


def test_limit_mode_slows_to_what_stays_clear_and_stops_at_contact(scans):
    judge = judge_for("limit")
    open_room = judge.limit(Twist(0.3, 0.0), view_of(scans.open(), scans))
    assert open_room.ok and open_room.factor == 1.0
    near = judge.limit(Twist(0.3, 0.0), view_of(scans.wall_at(0.5), scans))
    assert near.ok and 0.0 < near.factor < 1.0 and near.safe["slowed_to_m_s"] < 0.3
    fast = judge.limit(Twist(1.0, 0.0), view_of(scans.open(), scans))
    assert fast.factor == pytest.approx(0.5) and "max_velocity" in fast.reasons[0]
    touching = judge.limit(Twist(0.3, 0.0), view_of(scans.wall_at(0.2), scans))
    assert not touching.ok and touching.factor == 0.0
