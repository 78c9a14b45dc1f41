"""A pilot's plan as a publish_for_durations call at the room's speeds, and guard-mcp's refusal of it as a verdict."""

from __future__ import annotations

import math

import pytest

from safeembodai_core.mcp_agent.motions import (
    STOP_S, Speeds, motion_arguments, refusal_body, runs_s, stop_only, twist, verdict,
)
from safeembodai_core.models import Straight, Turn


def straight(mm, forward=True):
    return Straight(command="straight", direction="forward" if forward else "backward", distance=mm)


def turn(deg, left=True):
    return Turn(command="turn", direction="left" if left else "right", angle=deg)


def test_each_signal_is_one_twist_held_for_its_distance_at_the_rooms_speed_then_a_stop():
    arguments = motion_arguments([straight(399), turn(45, left=False), straight(100, forward=False)],
                                 Speeds(linear_mm_s=200.0, turn_deg_s=60.0))
    assert arguments["topic"] == "/cmd_vel" and arguments["msg_type"] == "geometry_msgs/msg/Twist"
    assert arguments["rate_hz"] == 10.0  # streamed: a base holds a message only for its cmd_vel_timeout
    assert arguments["durations"] == [pytest.approx(1.995), pytest.approx(0.75), pytest.approx(0.5), STOP_S]
    go, right, back, stop = arguments["messages"]
    assert go == twist(0.2) and back == twist(-0.2) and stop == twist()
    assert right["angular"]["z"] == pytest.approx(-math.radians(60.0)) and right["linear"]["x"] == 0.0
    assert runs_s(arguments) == pytest.approx(1.995 + 0.75 + 0.5 + STOP_S)


def test_every_message_is_a_whole_twist():
    """guard-mcp refuses a partial message (rosbridge would fill it with zeros)."""
    for message in motion_arguments([turn(10), straight(50)], Speeds())["messages"]:
        assert set(message) == {"linear", "angular"}
        assert all(set(part) == {"x", "y", "z"} for part in message.values())


def test_an_empty_plan_is_a_stop_alone():
    arguments = motion_arguments([], Speeds())
    assert arguments["messages"] == [twist()] and arguments["durations"] == [STOP_S]


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), float("inf")])
def test_speeds_must_be_positive_numbers(value):
    with pytest.raises(ValueError):
        Speeds(linear_mm_s=value)


def test_a_refusal_names_the_refused_signal_and_how_far_of_it_is_safe():
    body = {"refused": True, "reasons": ["messages[1] held 2 s: refused on the robot's own scan"],
            "advice": ["at most 180 mm of messages[1] is safe (0.90 s at this speed)"],
            "safe": {"message": 1, "at_most_mm": 180.0, "at_most_deg": 0.0}, "stop_only": False}
    refused = verdict(refusal_body(body), [turn(20), straight(399)])
    assert not refused.valid and refused.rule == "guard_mcp" and refused.signal_index == 1
    assert refused.advice.safe_mm == 180.0 and refused.advice.safe_deg is None
    assert "at most 180 mm" in refused.reason and not stop_only(body)


def test_a_refused_turn_says_its_safe_degrees():
    body = {"refused": True, "safe": {"message": 0, "at_most_mm": 0.0, "at_most_deg": 12.5}}
    assert verdict(body, [turn(80)]).advice.safe_deg == 12.5


@pytest.mark.parametrize("safe", [{}, {"message": 7}, {"message": True}, {"message": "0"}, {"message": -1}])
def test_a_refusal_that_names_no_signal_of_the_plan_gives_no_advice(safe):
    refused = verdict({"refused": True, "reasons": ["no scan yet"], "safe": safe}, [straight(100)])
    assert refused.signal_index is None and refused.advice is None and refused.reason == "no scan yet"


def test_a_motion_stopped_midway_keeps_its_reasons_under_guard():
    body = {"refused": True, "guard": {"verdict": "stopped", "reasons": ["a ball stepped in"],
                                       "safe": {"message": 0, "at_most_mm": 40.0}}, "stop_only": True}
    refused = verdict(body, [straight(300)])
    assert refused.advice.safe_mm == 40.0 and "a ball stepped in" in refused.reason and stop_only(body)


@pytest.mark.parametrize("content", [{"success": True}, {"refused": "yes"}, "refused", None, [1]])
def test_only_a_body_that_says_refused_true_is_a_refusal(content):
    assert refusal_body(content) is None


def test_hostile_numbers_in_a_refusal_give_no_advice_value():
    refused = verdict({"refused": True, "safe": {"message": 0, "at_most_mm": float("nan")}}, [straight(100)])
    assert refused.advice is not None and refused.advice.safe_mm is None
