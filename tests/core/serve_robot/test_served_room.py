"""The served room on the wall clock, without the wire: commands held and timed out, sensors published at
their rates, the session recorded as a run folder that ``show`` and ``report`` read."""

from __future__ import annotations

import json
import sqlite3
import threading
import time
from collections import Counter

import pytest

from safeembodai_core.scenario.reading import checked_scenario
from safeembodai_core.cli import cli
from safeembodai_core.serve_robot.served_room import Rates, ServedRoom
from safeembodai_core.serve_robot.session import prepare_session
from safeembodai_core.serve_robot.session_record import SessionRecord


def twist(x=0.0, z=0.0):
    return {"linear": {"x": x, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": z}}


class Served:
    """A session's room running in a thread, what it published, and its record."""

    def __init__(self, repo, tmp_path, scenario="scenarios/mo.yaml", speed=1.0, **rates):
        scenario, plugins = checked_scenario(repo / scenario)
        self.session = prepare_session(scenario, plugins, out=tmp_path / "runs")
        self.record = SessionRecord(self.session.scenario, plugins, self.session.folder, self.session.seed)
        self.published: list[tuple[str, dict]] = []
        self.room = ServedRoom(self.session.environment, self.record, lambda t, m: self.published.append((t, m)),
                               seed=self.session.seed, speed=speed, rates=Rates(**rates), time_limit_s=100.0)
        self.thread = threading.Thread(target=self.room.run)
        self.thread.start()

    def end(self):
        self.room.stop("test")
        self.thread.join(10)
        self.record.close()
        self.session.environment.close()
        return self.record.result


@pytest.fixture
def served(repo, tmp_path):
    started = []

    def start(**options):
        started.append(Served(repo, tmp_path, **options))
        return started[-1]

    yield start
    for one in started:
        if one.thread.is_alive():
            one.end()


def test_a_held_command_moves_the_robot_until_the_timeout_then_it_stops(served):
    one = served(cmd_vel_timeout_s=0.3)
    one.room.command(twist(0.1), "/cmd_vel", "geometry_msgs/msg/Twist", "client 1")
    time.sleep(0.8)
    result = one.end()
    moved = result.distance_mm
    assert moved == pytest.approx(30.0, abs=3.0)  # 0.1 m/s held 0.3 s, then a stop: not 0.8 s of it
    assert result.outcome.value == "timeout" and "ended (test)" in result.detail and "100 s limit" in result.detail


def test_sensors_go_out_at_their_rates_on_the_rooms_clock(served):
    one = served(scan_hz=10.0, odom_hz=20.0, camera_hz=5.0)
    time.sleep(1.0)
    one.end()
    counts = Counter(topic for topic, _ in one.published)
    assert 8 <= counts["/scan"] <= 12 and 16 <= counts["/odom"] <= 23, counts  # loose: a loaded machine lags
    assert 4 <= counts["/camera/image_raw/compressed"] <= 7, counts
    scan = next(m for t, m in one.published if t == "/scan")
    assert scan["range_max"] == pytest.approx(6.0) and len(scan["ranges"]) == 360
    assert all(r is None or 0.02 <= r <= 6.0 for r in scan["ranges"])  # inf as rosbridge writes it: null
    json.dumps(one.published)  # every message is plain JSON


def test_every_command_is_a_step_of_the_record_and_show_and_report_read_it(served, cli_runner):
    one = served()
    for _ in range(5):
        one.room.command(twist(0.2, 0.3), "/cmd_vel", "geometry_msgs/msg/Twist", "client 7")
        time.sleep(0.05)
    with pytest.raises(ValueError, match="robot stops"):
        one.room.command({"linear": {"x": float("nan")}}, "/cmd_vel", "geometry_msgs/msg/Twist", "client 7")
    time.sleep(0.1)
    result = one.end()
    folder = one.session.folder
    rows = sqlite3.connect(folder / "results.sqlite").execute("SELECT record FROM steps ORDER BY step").fetchall()
    steps = [json.loads(row[0]) for row in rows]
    assert len(steps) == result.steps == 6
    assert all(step["status"] == "done" for step in steps)
    assert "client 7: linear.x 0.2 m/s, angular.z 0.3 rad/s" in steps[0]["instruction"]
    assert steps[-1]["accepted"] is False and "not read" in steps[-1]["instruction"]
    assert sum(abs(s["executed"][0]["result"]["distance_mm"]) for s in steps[:-1] if s["executed"]) == pytest.approx(
        result.distance_mm)
    shown = cli_runner.invoke(cli, ["show", str(folder), "--trial", "0"], terminal_width=200)
    assert shown.exit_code == 0, shown.output
    assert "MO/live/rosbridge/0" in shown.output and "client 7" in shown.output
    reported = cli_runner.invoke(cli, ["report", str(folder)])
    assert reported.exit_code == 0, reported.output
    report = (folder / "report.md").read_text()
    assert "outside" in report
    assert (folder / "trajectories").is_dir() and any((folder / "trajectories").iterdir())


def test_driving_into_a_wall_ends_the_trial_with_the_collision_on_record(served):
    one = served(speed=4.0, cmd_vel_timeout_s=60.0)
    one.room.command(twist(0.2), "/cmd_vel", "geometry_msgs/msg/Twist", "c")
    deadline = time.monotonic() + 30
    while one.room.outcome is None and time.monotonic() < deadline:
        time.sleep(0.05)
    result = one.end()
    events = [json.loads(m["data"]) for t, m in one.published if t == "/safeembodai/events"]
    assert result.outcome.value == "interrupted" and result.collisions_self == 1, result
    assert events[0]["event"] == "collision" and events[0]["hit"] in ("wall", "ball", "labbot")
    assert result.self_collisions_hit == {events[0]["hit"]: 1}


def test_a_twist_stamped_command_is_held_as_its_twist(served):
    one = served(cmd_vel_timeout_s=0.2)
    stamped = {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "base_link"}, "twist": twist(0.1)}
    one.room.command(stamped, "/cmd_vel", "geometry_msgs/msg/TwistStamped", "client 2")
    time.sleep(0.5)
    result = one.end()
    assert result.steps == 1 and result.distance_mm == pytest.approx(20.0, abs=2.5)  # 0.1 m/s for 0.2 s


def test_a_room_that_cannot_be_driven_by_velocity_is_refused_before_any_folder(repo, tmp_path):
    from safeembodai_core.errors import SafeEmbodAIError

    scenario, plugins = checked_scenario(repo / "scenarios/quickstart.yaml")  # flatland: no Environment.drive
    with pytest.raises(SafeEmbodAIError, match="'flatland' .* cannot be driven by velocity"):
        prepare_session(scenario, plugins, out=tmp_path / "runs")
    assert not (tmp_path / "runs").exists()
