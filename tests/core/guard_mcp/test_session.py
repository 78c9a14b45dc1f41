"""A guard-mcp session as a run folder: every call a step (the call in words, the guard's verdicts, what ran, the
pose before and after), the result written when it ends; ``show``, ``report`` and ``view`` read it."""

from __future__ import annotations

import json
import sqlite3

import pytest

from safeembodai_core.cli import cli

TWIST = "geometry_msgs/msg/Twist"


@pytest.fixture
def recorded(rig, scans, tmp_path, built_plugins):
    """A rig whose calls go to a session's run folder: a safe drive, a drive into a wall, a read-only call and an
    unmapped one; the session finished."""
    from safeembodai_core.guard_mcp.session import CallSession

    r = rig()
    session = CallSession(r.mcp.policy, built_plugins, tmp_path / "runs", rosbridge="ws://127.0.0.1:9090",
                          upstream="ros-mcp")
    r.mcp.on_call = session.record
    r.see(scans.open())
    r.senses.on_odom(odometry(0.0))
    r.during_slice = lambda arguments: r.senses.on_odom(odometry(0.1 * len(r.slices)))  # 100 mm a slice
    r.call("publish_for_durations", topic="/cmd_vel", msg_type=TWIST, messages=[scans.twist(0.5)], durations=[0.4])
    r.see(scans.wall_at(0.6))
    r.call("publish_for_durations", topic="/cmd_vel", msg_type=TWIST, messages=[scans.twist(0.3)], durations=[5.0])
    r.call("get_topics")
    r.call("format_disk", path="/")
    session.finish(r.mcp, "guard-mcp ended (its client left)")
    return session


def odometry(x_m):
    return {"pose": {"pose": {"position": {"x": x_m, "y": 0.0, "z": 0.0},
                              "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}}


def steps_of(folder):
    rows = sqlite3.connect(folder / "results.sqlite").execute("SELECT record FROM steps ORDER BY step").fetchall()
    return [json.loads(row[0]) for row in rows]


def test_every_call_is_a_step_with_its_verdicts_what_ran_and_the_poses(recorded):
    drive, wall, topics, unmapped = steps_of(recorded.path)
    assert drive["instruction"] == ("publish_for_durations on /cmd_vel (geometry_msgs/msg/Twist): linear.x 0.5 m/s, "
                                    "angular.z 0 rad/s for 0.4 s")
    assert drive["accepted"] and drive["attempts"][0]["verdicts"][0]["valid"]
    [executed] = drive["executed"]
    assert executed["signal"] == {"command": "straight", "direction": "forward", "distance": 200.0,
                                  "justification": ""}  # as odometry measured it
    assert "commanded 200 mm" in executed["result"]["detail"]
    assert drive["pose_before"]["x_mm"] == 0.0 and drive["pose_after"]["x_mm"] == 200.0
    assert not wall["accepted"] and not wall["executed"]
    assert {v["rule"] for v in wall["attempts"][0]["verdicts"]} == {"guard"}
    assert any("swept_body" in v["reason"] for v in wall["attempts"][0]["verdicts"])
    assert topics["accepted"] and topics["attempts"][0]["verdicts"][0]["rule"] == "policy"
    assert not unmapped["accepted"] and "maps no such tool" in unmapped["attempts"][0]["verdicts"][0]["reason"]
    assert recorded.result.steps == 4 and recorded.result.interventions == 2
    assert recorded.result.distance_mm == pytest.approx(200.0)
    assert recorded.result.outcome.value == "timeout" and "its client left" in recorded.result.detail


def test_show_report_and_view_read_the_session(recorded, cli_runner, built_plugins, tmp_path):
    from safeembodai_core.view.site import build_site

    shown = cli_runner.invoke(cli, ["show", str(recorded.path), "--trial", "0"], terminal_width=200)
    assert shown.exit_code == 0, shown.output
    assert "robot/guard-mcp/mcp/0" in shown.output and "publish_for_durations on /cmd_vel" in shown.output
    assert "guard (signal" not in shown.output and "x guard: " in shown.output  # the wall's refusal, by the guard
    assert "cannot be told" not in shown.output  # the recorded scenario reads back: outside robot, outside client
    reported = cli_runner.invoke(cli, ["report", str(recorded.path)])
    assert reported.exit_code == 0, reported.output
    assert "outside MCP client" in (recorded.path / "report.md").read_text()
    build_site(recorded.path, tmp_path / "site", built_plugins)
    pages = "".join(page.read_text() for page in (tmp_path / "site").rglob("*.html"))
    assert "robot/guard-mcp/mcp/0" in pages and "publish_for_durations on /cmd_vel" in pages


def test_stop_only_at_the_end_is_a_safe_abort(rig, scans, tmp_path, built_plugins):
    from safeembodai_core.guard_mcp.session import CallSession

    r = rig()
    session = CallSession(r.mcp.policy, built_plugins, tmp_path, rosbridge="ws://127.0.0.1:9090", upstream="x")
    r.mcp.on_call = session.record
    for _ in range(3):
        r.call("set_parameter", name="/base:max_speed", value="9")
    session.finish(r.mcp)
    session.finish(r.mcp)  # once is enough, twice does no harm
    assert session.result.outcome.value == "safe_abort" and "left only stops answered" in session.result.detail
