"""GuardMcp with a fake upstream: what reaches the upstream for each call, and what the agent is answered."""

from __future__ import annotations

import asyncio

import pytest

from safeembodai_core.guard_mcp.policy import Failures

TWIST = "geometry_msgs/msg/Twist"


def drive(r, scans, x=0.2, seconds=1.0, **arguments):
    return r.call("publish_for_durations", topic="/cmd_vel", msg_type=TWIST, messages=[scans.twist(x)],
                  durations=[seconds], **arguments)


def test_a_safe_drive_runs_in_slices_of_the_policys_length(rig, scans):
    r = rig()
    r.see(scans.open())
    error, body = drive(r, scans, rate_hz=0)
    assert not error, body
    assert [s["durations"][0] for s in r.slices] == pytest.approx([0.2] * 5)
    assert all(s["rate_hz"] == 10 and s["messages"] == [scans.twist(0.2)] for s in r.slices)
    assert body["guard"]["verdict"] == "forwarded" and body["published_count"] == 10 and not r.stops


def test_publish_once_goes_out_at_once_as_one_publish_in_the_policys_spelling(rig, scans):
    r = rig()
    r.see(scans.open())
    error, body = r.call("publish_once", topic="cmd_vel", msg_type="geometry_msgs/Twist", msg=scans.twist(0.1))
    assert not error and body["success"]
    assert r.sent == [("publish_for_durations", {"topic": "/cmd_vel", "msg_type": TWIST, "durations": [0.0],
                                                 "messages": [scans.twist(0.1)], "rate_hz": 0})]


@pytest.mark.parametrize("age_s", [None, 0.6])
def test_no_scan_yet_or_a_stale_one_refuses_every_motion_and_sends_nothing(rig, scans, age_s):
    r = rig()
    if age_s is not None:
        r.see(scans.open())
        r.clock.now += age_s
    error, body = drive(r, scans)
    assert error and body["refused"] and not r.sent
    assert ("no scan yet" if age_s is None else "0.60 s old") in body["reasons"][0]


def test_a_stop_goes_out_even_blind(rig, scans):
    r = rig()
    error, _ = r.call("publish_once", topic="/cmd_vel", msg_type=TWIST, msg=scans.twist(0.0))
    assert not error and len(r.sent) == 1


def test_a_drive_into_a_wall_is_refused_with_reasons_advice_and_numbers_and_sends_nothing(rig, scans):
    r = rig()
    r.see(scans.wall_at(1.0))
    error, body = drive(r, scans, seconds=6.0)
    assert error and not r.sent
    assert body["safe"]["at_most_mm"] == pytest.approx(780.0, abs=10.0)
    assert "at most 7" in body["advice"][0] and body["refusals_in_a_row"] == 1


def test_an_obstacle_appearing_mid_motion_stops_it_with_a_stop_of_guard_mcps_own(rig, scans):
    r = rig()
    r.see(scans.open())

    def world(arguments):
        if len(r.slices) == 3:  # while the third slice runs, something steps in 0.35 m ahead
            r.latest = scans.wall_at(0.35)

    r.during_slice = world
    error, body = drive(r, scans, seconds=3.0)
    assert error and body["guard"]["verdict"] == "stopped" and len(r.slices) == 3
    assert body["guard"]["reasons"][0].startswith("stopped 0.60 s into the motion")
    assert r.stops == [("/cmd_vel", scans.twist(0.0))]
    assert body["refusals_in_a_row"] == 1


def test_limit_mode_sends_the_slowed_message_and_says_so(rig, scans):
    r = rig(mode="limit")
    r.see(scans.wall_at(0.55))
    error, body = drive(r, scans, x=0.4, seconds=0.4)
    assert not error and body["guard"]["verdict"] == "limited" and body["guard"]["reasons"]
    sent = [s["messages"][0]["linear"]["x"] for s in r.slices]
    assert sent and all(0.0 < x < 0.4 for x in sent)


def test_limit_mode_refuses_what_cannot_move_at_all(rig, scans):
    r = rig(mode="limit")
    r.see(scans.wall_at(0.2))
    error, body = drive(r, scans)
    assert error and body["refused"] and not r.sent


def test_an_upstream_failure_mid_motion_stops_the_robot(rig, scans):
    r = rig()
    r.see(scans.open())
    r.fail_slices = True
    error, body = drive(r, scans)
    assert error and body["guard"]["verdict"] == "failed" and "rosbridge refused it" in body["guard"]["reasons"][1]
    assert r.stops and len(r.slices) == 1


def test_after_the_threshold_only_stops_are_answered_until_reset(rig, scans):
    r = rig()
    r.see(scans.wall_at(1.0))
    for _ in range(3):
        assert drive(r, scans, seconds=9.0)[0]
    error, body = drive(r, scans, seconds=0.5)  # safe, but the agent is now answered only stops
    assert error and body["stop_only"] and "only stops" in body["reasons"][0] and not r.sent
    assert not r.call("publish_once", topic="/cmd_vel", msg_type=TWIST, msg=scans.twist(0.0))[0]
    r.mcp.reset()
    r.see(scans.wall_at(1.0))
    assert not drive(r, scans, seconds=0.5)[0]


def test_continue_lets_the_agent_go_on_and_a_forwarded_call_clears_the_streak(rig, scans):
    r = rig(failures=Failures(threshold=2, then="continue"))
    r.see(scans.wall_at(1.0))
    for _ in range(3):
        drive(r, scans, seconds=9.0)
    assert r.mcp.refusals_in_a_row == 3 and not r.mcp.stop_only
    assert not drive(r, scans, seconds=0.5)[0] and r.mcp.refusals_in_a_row == 0


def test_a_read_only_call_passes_through_and_a_refused_one_is_recorded(rig, scans):
    r = rig()
    error, body = r.call("get_topics")
    assert not error and body["untrusted_data"] == {"upstream": "get_topics", "arguments": {}}
    r.call("set_parameter", name="/base:max_speed", value="9")
    assert [(c.tool, c.verdict) for c in r.mcp.calls] == [("get_topics", "read_only"), ("set_parameter", "refused")]
    assert r.mcp.refusals_in_a_row == 1 and r.sent == [("get_topics", {})]


def test_motions_asked_at_once_run_one_after_the_other(rig, scans):
    r = rig()
    r.see(scans.open())

    async def both():
        first = r.mcp.call("publish_for_durations", {"topic": "/cmd_vel", "msg_type": TWIST,
                                                     "messages": [scans.twist(0.1)], "durations": [0.6]})
        second = r.mcp.call("publish_for_durations", {"topic": "/cmd_vel", "msg_type": TWIST,
                                                      "messages": [scans.twist(0.3)], "durations": [0.6]})
        return await asyncio.gather(first, second)

    results = asyncio.run(both())
    assert not any(result.isError for result in results)
    speeds = [s["messages"][0]["linear"]["x"] for s in r.slices]
    assert speeds == sorted(speeds) and set(speeds) == {0.1, 0.3}
