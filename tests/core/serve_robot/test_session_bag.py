"""A serve-robot session's own ROS 2 bag, read back with ``mcap`` + ``mcap_ros2`` (a reader no one here
wrote), against the session's run folder; and ``safeembodai export`` of a session, which copies that bag
instead of replaying (a session has no answers to replay)."""

from __future__ import annotations

import json
import math
import shutil
import sqlite3
import threading
import time
from pathlib import Path

import pytest

from safeembodai_core.cli import cli
from safeembodai_core.serve_robot.session_bag import TOPICS
from safeembodai_core.runs.trial_files import bag_file

pytest.importorskip("mcap_ros2", reason="the dev extra's independent MCAP reader (pip install -e '.[dev]')")

TRIAL = "OF/live/rosbridge/0"
SENT = [(0.0, 0.5), (0.1, 0.0), None, (0.1, 0.2)]  # None: a command the room cannot read


def twist(x, z):
    return {"linear": {"x": x, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": z}}


def serve(repo, out, bag="mcap"):
    """A session of the obstacle-free room in its own thread (as ``serve-robot`` runs it): (session, thread)."""
    from safeembodai_core.scenario.reading import checked_scenario
    from safeembodai_core.serve_robot.session import prepare_session

    scenario, plugins = checked_scenario(repo / "scenarios/of.yaml")
    session = prepare_session(scenario, plugins, out=out, port=0, bag=bag)
    ready = threading.Event()
    thread = threading.Thread(target=session.serve, kwargs={"on_ready": lambda _: ready.set()}, daemon=True)
    thread.start()
    assert ready.wait(20), "serve-robot did not start"
    return session, thread


def end(session, thread):
    session.stop("test")
    thread.join(20)
    assert not thread.is_alive()
    return session.folder


@pytest.fixture(scope="module")
def session_folder(repo, tmp_path_factory):
    """One session driven through the room's command entry (no network client), ended by ``stop()`` while
    the last command is still held (the robot moving)."""
    session, thread = serve(repo, tmp_path_factory.mktemp("served"))
    try:
        for command in SENT:
            if command is None:
                with pytest.raises(ValueError, match="robot stops"):
                    session.room.command({"linear": {"x": math.nan}}, "/cmd_vel", "geometry_msgs/msg/Twist", "c9")
                time.sleep(0.15)
            else:
                session.room.command(twist(*command), "/cmd_vel", "geometry_msgs/msg/Twist", "c9")
                time.sleep(0.3)
    finally:
        folder = end(session, thread)
    return folder


def read_mcap(folder: Path) -> list[tuple[str, int, object]]:
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    files = list(folder.glob("*.mcap"))
    assert len(files) == 1, files
    out = []
    with files[0].open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        assert reader.get_summary() is not None, "the MCAP has no summary: the bag was not finished"
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
            assert schema.encoding == "ros2msg" and schema.name == TOPICS[channel.topic], channel.topic
            out.append((channel.topic, message.log_time, decoded))
    return out


def recorded(folder: Path):
    """The session's steps and result as its run folder holds them."""
    store = sqlite3.connect(folder / "results.sqlite")
    try:
        steps = [json.loads(r[0]) for r in store.execute("SELECT record FROM steps ORDER BY step")]
        result = json.loads(store.execute("SELECT result FROM trials").fetchone()[0])
    finally:
        store.close()
    return steps, result


def stamp_s(header) -> float:
    return header.stamp.sec + header.stamp.nanosec * 1e-9


def test_the_bag_holds_every_command_and_every_pose_the_record_holds(session_folder):
    messages = read_mcap(bag_file(session_folder, TRIAL))
    steps, result = recorded(session_folder)
    assert len(steps) == len(SENT) == result["steps"]
    commands = [(t, m) for topic, t, m in messages if topic == "/cmd_vel"]
    warnings = [(t, m) for topic, t, m in messages if topic == "/rosout" and m.level == 30]
    assert len(commands) == 3 and len(warnings) == 1
    taken = iter(commands)
    for step, sent in zip(steps, SENT):
        if sent is None:
            t, log = warnings[0]
            assert not step["accepted"] and "not read" in log.msg and "from c9" in log.msg
        else:
            t, command = next(taken)
            assert (command.linear.x, command.angular.z) == pytest.approx(sent)
        assert t == pytest.approx(step["sim_time_s"] * 1e9, abs=1000)  # taken when the record says, to 1 us

    # the record's path: a pose at each scan served, and the last at the end; each lies on the bag's
    # odometry where the room was at the scan's time (between two odometry ticks: at most 0.1 m/s apart)
    scans = [m for topic, _, m in messages if topic == "/scan"]
    odometry = [(stamp_s(m.header), m.pose.pose.position) for topic, _, m in messages if topic == "/odom"]
    path = result["trajectory"]
    assert len(scans) == len(path) - 1 and len(scans) >= 8
    checked = 0
    for scan, pose in zip(scans, path):
        t = stamp_s(scan.header)
        around = [(t0, p0, t1, p1) for (t0, p0), (t1, p1) in zip(odometry, odometry[1:]) if t0 <= t <= t1]
        if not around:
            continue
        t0, p0, t1, p1 = around[0]
        share = (t - t0) / (t1 - t0) if t1 > t0 else 0.0
        x, y = p0.x + share * (p1.x - p0.x), p0.y + share * (p1.y - p0.y)
        assert math.dist((x, y), (pose["x_mm"] / 1000, pose["y_mm"] / 1000)) <= 0.1 * (t1 - t0) / 2 + 1e-6
        checked += 1
    assert checked >= len(scans) - 2
    ended = [t for topic, t, m in messages if topic == "/safeembodai/trial" and "result" in m.data][0] / 1e9
    (t_last, last) = odometry[-1]  # the last pose, at the end: at most 0.1 m/s from the last odometry
    assert 0 <= ended - t_last < 1.0
    end_pose = (path[-1]["x_mm"] / 1000, path[-1]["y_mm"] / 1000)
    assert math.dist((last.x, last.y), end_pose) <= 0.1 * (ended - t_last) + 1e-6
    moved = [(p["x_mm"], p["y_mm"]) for p in path]
    assert max(math.dist(moved[0], p) for p in moved) > 10.0  # the robot did move: the poses are not all one


def test_a_session_ended_by_stop_leaves_a_whole_bag_in_place(session_folder):
    bags = session_folder / "bags"
    assert sorted(p.name for p in bags.iterdir()) == ["OF__live__rosbridge__0", "storage"]  # no scratch left
    assert (bags / "storage").read_text().strip() == "mcap"
    messages = read_mcap(bag_file(session_folder, TRIAL))
    _, result = recorded(session_folder)
    topics = {topic for topic, _, _ in messages}
    assert topics >= {"/scan", "/odom", "/tf", "/pose", "/clock", "/camera/image_raw/compressed", "/cmd_vel",
                      "/rosout", "/safeembodai/events", "/safeembodai/trial"}
    trial = [json.loads(m.data) for topic, _, m in messages if topic == "/safeembodai/trial"]
    assert trial[0]["trial"]["trial_id"] == TRIAL and trial[0]["trial"]["seed"] == 0
    assert trial[-1]["result"]["outcome"] == result["outcome"] == "timeout"
    assert "ended (test)" in trial[-1]["result"]["detail"]
    events = [json.loads(m.data) for topic, _, m in messages if topic == "/safeembodai/events"]
    assert events[-1]["event"] == "session_ended"
    times = [t for _, t, _ in messages]
    assert times == sorted(times)  # one clock, in the order things happened


def test_export_of_a_session_writes_its_bag_again_in_either_format(session_folder, tmp_path, cli_runner):
    from rosbags.rosbag2 import Reader

    out = tmp_path / "exported"
    done = cli_runner.invoke(cli, ["export", str(session_folder), "--out", str(out)])
    assert done.exit_code == 0, done.output
    assert "replay" not in done.output
    exported = read_mcap(out / "OF__live__rosbridge__0")
    original = read_mcap(bag_file(session_folder, TRIAL))
    assert [(topic, t) for topic, t, _ in exported] == [(topic, t) for topic, t, _ in original]
    assert [m.data for topic, _, m in exported if topic == "/safeembodai/trial"] == \
        [m.data for topic, _, m in original if topic == "/safeembodai/trial"]

    as_sqlite = tmp_path / "as-sqlite"
    done = cli_runner.invoke(cli, ["export", str(session_folder), "--trial", TRIAL, "--format", "sqlite3",
                                   "--out", str(as_sqlite)])
    assert done.exit_code == 0, done.output
    assert list(as_sqlite.glob("*.db3"))
    with Reader(as_sqlite) as reader:
        assert reader.message_count == len(original)

    refused = cli_runner.invoke(cli, ["export", str(session_folder), "--format", "rrd", "--out",
                                      str(tmp_path / "r")])
    words = str(refused.exception or refused.output)
    assert refused.exit_code != 0 and "serve-robot session" in words and "--format mcap" in words


def test_export_of_a_session_without_a_bag_says_why_and_how(repo, tmp_path, cli_runner):
    folder = end(*serve(repo, tmp_path / "runs", bag=None))
    assert not (folder / "bags").exists()
    done = cli_runner.invoke(cli, ["export", str(folder), "--out", str(tmp_path / "out")])
    assert done.exit_code != 0
    words = " ".join(str(done.exception or done.output).split())
    assert "serve-robot session" in words and "cannot be replayed" in words and "--bag none" in words, words
    assert "differs from the recording" not in words
    assert not (tmp_path / "out").exists()


def test_export_of_a_session_whose_bag_was_never_finished_says_so(session_folder, tmp_path, cli_runner):
    folder = tmp_path / "killed"
    shutil.copytree(session_folder, folder)
    shutil.rmtree(bag_file(folder, TRIAL))  # what a SIGKILL leaves: the marker, no bag in place
    done = cli_runner.invoke(cli, ["export", str(folder), "--out", str(tmp_path / "out")])
    assert done.exit_code != 0
    words = " ".join(str(done.exception or done.output).split())
    assert "did not end cleanly" in words and "is missing" in words, words


def test_a_session_served_with_a_sqlite_bag_keeps_it_and_exports_it_as_mcap(repo, tmp_path, cli_runner):
    session, thread = serve(repo, tmp_path / "runs", bag="sqlite3")
    try:
        session.room.command(twist(0.0, 0.4), "/cmd_vel", "geometry_msgs/msg/Twist", "c2")
        time.sleep(0.3)
    finally:
        folder = end(session, thread)
    database = next(bag_file(folder, TRIAL).glob("*.db3"))
    store = sqlite3.connect(database)
    try:
        counts = dict(store.execute("SELECT topics.name, COUNT(*) FROM messages JOIN topics ON topics.id = "
                                    "messages.topic_id GROUP BY topics.name"))
    finally:
        store.close()
    assert counts["/cmd_vel"] == 1 and counts["/scan"] >= 2 and counts["/safeembodai/trial"] == 2, counts
    out = tmp_path / "as-mcap"
    done = cli_runner.invoke(cli, ["export", str(folder), "--trial", TRIAL, "--out", str(out)])
    assert done.exit_code == 0, done.output
    exported = read_mcap(out)
    assert len(exported) == sum(counts.values())
    assert [m.angular.z for topic, _, m in exported if topic == "/cmd_vel"] == [pytest.approx(0.4)]
