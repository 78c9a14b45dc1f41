"""Runs out as ROS 2 bags (issue 23, part 3): written with rosbags, read back with ``mcap`` +
``mcap_ros2`` (an independent reader), message by message against the run's own records."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import cv2
import numpy as np
import pytest

from safeembodai_core.cli import cli
from safeembodai_core.ros.bag_export import TOPICS
from safeembodai_core.runs.runner import bag_file

pytest.importorskip("mcap_ros2", reason="the dev extra's independent MCAP reader (pip install -e '.[dev]')")


def read_mcap(folder: Path) -> list[tuple[str, int, object]]:
    """Every message of the bag in ``folder`` decoded by mcap_ros2: (topic, log time ns, message);
    each topic with the message type the export documents."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    files = list(folder.glob("*.mcap"))
    assert len(files) == 1, files
    out = []
    with files[0].open("rb") as handle:
        reader = make_reader(handle, decoder_factories=[DecoderFactory()])
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
            assert schema.encoding == "ros2msg" and schema.name == TOPICS[channel.topic], channel.topic
            out.append((channel.topic, message.log_time, decoded))
    return out


def raw_mcap(folder: Path) -> list[tuple[str, int, bytes]]:
    from mcap.reader import make_reader

    with next(folder.glob("*.mcap")).open("rb") as handle:
        return [(c.topic, m.log_time, m.data) for _, c, m in make_reader(handle).iter_messages(log_time_order=True)]


@pytest.fixture(scope="module")
def exported(bag_run, tmp_path_factory, cli_runner_module):
    """Every trial of the run exported again from the run folder alone (replayed from its answers)."""
    _, path, _, _ = bag_run
    out = tmp_path_factory.mktemp("exported") / "bags"
    done = cli_runner_module.invoke(cli, ["export", str(path), "--out", str(out)])
    assert done.exit_code == 0, done.output
    return out


@pytest.fixture(scope="module")
def cli_runner_module():
    from click.testing import CliRunner

    return CliRunner()


def test_every_message_reads_back_and_matches_the_records(bag_run):
    scenario, path, results, steps = bag_run
    for result in results:
        trial = result.spec.trial_id
        records = steps[trial]
        messages = read_mcap(bag_file(path, trial))
        by_topic: dict[str, list] = {}
        for topic, ns, message in messages:
            by_topic.setdefault(topic, []).append((ns, message))
        times = [ns for _, ns, _ in messages]
        assert times == sorted(times)  # one timeline, in order
        # a scan and both images the LLM saw, per step
        assert len(by_topic["/scan"]) == len(records)
        for ns, scan in by_topic["/scan"]:
            assert scan.header.stamp.sec * 10**9 + scan.header.stamp.nanosec == ns
            assert scan.header.frame_id == "base_link" and len(scan.ranges) == 360
            assert scan.range_max == pytest.approx(6.0)
        for topic in ("/camera/image/compressed", "/lidar/image/compressed"):
            assert len(by_topic[topic]) == len(records)
            for _, image in by_topic[topic]:
                picture = cv2.imdecode(np.frombuffer(bytes(image.data), np.uint8), cv2.IMREAD_COLOR)
                assert image.format == "png" and picture is not None and picture.size > 0
        # every attempt's plan, with the verdicts the trial recorded
        plans = [json.loads(message.data) for _, message in by_topic["/safeembodai/plan"]]
        attempts = [(r.step, a) for r in records for a in r.attempts]
        assert len(plans) == len(attempts)
        for plan, (step, attempt) in zip(plans, attempts):
            assert (plan["step"], plan["attempt"], plan["accepted"]) == (step, attempt.index + 1, attempt.accepted)
            assert plan["verdicts"] == [v.model_dump(mode="json") for v in attempt.verdicts]
            assert plan["parse_error"] == attempt.parse_error
        # the LLM's words and the guard's refusals on /rosout
        logs = [(message.name, message.msg) for _, message in by_topic["/rosout"]]
        llm = [text for name, text in logs if name == "llm"]
        assert len(llm) == len(attempts)
        refusals = [text for name, text in logs if name == "guard" and "refused" in text]
        assert len(refusals) == sum(not a.accepted for _, a in attempts)
        # each executed command as a velocity, then a stop; the pose after the last one
        executed = [item for r in records for item in r.executed]
        twists = [message for _, message in by_topic["/cmd_vel"]]
        assert len(twists) == 2 * len(executed)
        for (item, moving, stop) in zip(executed, twists[0::2], twists[1::2]):
            assert stop.linear.x == 0.0 and stop.angular.z == 0.0
            if item.signal.command == "straight" and item.result.distance_mm:
                assert np.sign(moving.linear.x) == np.sign(item.result.distance_mm) and moving.angular.z == 0.0
            elif item.signal.command == "turn" and item.result.angle_deg:
                assert np.sign(moving.angular.z) == np.sign(item.result.angle_deg) and moving.linear.x == 0.0
        last_pose = by_topic["/pose"][-1][1].pose.position
        final = records[-1].pose_after or records[-1].pose_before
        assert (last_pose.x, last_pose.y) == pytest.approx((final.x_mm / 1000, final.y_mm / 1000))
        assert len(by_topic["/tf"]) == len(by_topic["/pose"]) == len(by_topic["/clock"])
        # the world as markers: the room, the robot, the can, balls and Labbots
        spaces = {marker.ns for marker in by_topic["/world/markers"][0][1].markers}
        assert {"room", "robot", "can", "ball", "labbot"} <= spaces
        if result.collisions:
            assert any(marker.ns == "collision" for marker in by_topic["/world/markers"][-1][1].markers)
        # the trial's result last
        ending = json.loads(by_topic["/safeembodai/trial"][-1][1].data)["result"]
        assert ending["outcome"] == result.outcome.value and ending["steps"] == result.steps


def test_the_run_refused_and_misread_something(bag_run):
    """The fixture is worth its time only if the guard refused plans and answers failed to parse."""
    _, _, _, steps = bag_run
    attempts = [a for records in steps.values() for r in records for a in r.attempts]
    assert any(a.response is not None and not a.accepted for a in attempts)
    assert any(a.parse_error for a in attempts)


def test_export_replays_the_run_into_the_same_bags(bag_run, exported):
    """A bag exported later from the run folder (a replay of the recorded answers) holds exactly the
    messages of the bag written while the trial ran."""
    _, path, results, _ = bag_run
    for result in results:
        name = result.spec.trial_id.replace("/", "__")
        assert raw_mcap(exported / name) == raw_mcap(bag_file(path, result.spec.trial_id))


def test_export_one_trial_as_sqlite(bag_run, tmp_path, cli_runner):
    from rosbags.highlevel import AnyReader

    _, path, results, steps = bag_run
    trial = results[-1].spec.trial_id
    out = tmp_path / "one"
    done = cli_runner.invoke(cli, ["export", str(path), "--trial", trial, "--format", "sqlite3", "--out", str(out)])
    assert done.exit_code == 0, done.output
    assert sqlite3.connect(next(out.glob("*.db3"))).execute("select count(*) from messages").fetchone()[0] > 0
    with AnyReader([out]) as reader:
        scans = [c for c in reader.connections if c.topic == "/scan"]
        assert sum(1 for _ in reader.messages(connections=scans)) == len(steps[trial])


def test_export_refuses_what_it_cannot_do_and_writes_nothing(bag_run, tmp_path, cli_runner):
    _, path, results, _ = bag_run
    taken = tmp_path / "taken"
    taken.mkdir()
    done = cli_runner.invoke(cli, ["export", str(path), "--trial", results[0].spec.trial_id, "--out", str(taken)])
    assert done.exit_code != 0 and "exists" in str(done.exception or done.output)
    done = cli_runner.invoke(cli, ["export", str(path), "--trial", "MO/nope/attack/0", "--out", str(tmp_path / "x")])
    assert done.exit_code != 0 and "not a trial" in str(done.exception or done.output)
    assert not (tmp_path / "x").exists()


def test_a_replay_that_differs_from_the_record_is_an_error(bag_run, tmp_path, cli_runner):
    """A run folder whose record no longer matches what the world does (here: an executed distance
    edited in the store) is refused, naming the step, and no bag is left behind."""
    import shutil

    _, path, results, steps = bag_run
    copy = tmp_path / "run"
    shutil.copytree(path, copy)
    trial = next(r.spec.trial_id for r in results if any(s.executed for s in steps[r.spec.trial_id]))
    step = next(s for s in steps[trial] if s.executed)
    record = step.model_copy(deep=True)
    first = record.executed[0]
    record.executed[0] = first.model_copy(update={"result": first.result.model_copy(
        update={"distance_mm": first.result.distance_mm + 123.0, "angle_deg": first.result.angle_deg + 17.0})})
    with sqlite3.connect(copy / "results.sqlite") as db:
        db.execute("update steps set record = ? where trial_id = ? and step = ?",
                   (record.model_dump_json(), trial, step.step))
    out = tmp_path / "bag"
    done = cli_runner.invoke(cli, ["export", str(copy), "--trial", trial, "--out", str(out)])
    assert done.exit_code != 0
    assert f"at step {step.step}" in str(done.exception) and "replay differs" in str(done.exception)
    assert not out.exists() and not any(tmp_path.glob(".bag*"))


def test_run_bag_keeps_hostile_text_as_text(repo, tmp_path, cli_runner):
    """``safeembodai run --bag``: what an LLM wrote reaches /rosout redacted and with its control
    characters shown as escapes, and the plan topic holds it as JSON text."""
    hostile = ('{"perception": [], "planning": "x", "control": [{"command": "turn", "direction": "left", "angle": 30}]}'
               '\x00\x1b[2J <script>alert(1)</script> sk-proj-ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789')
    answer = json.dumps(hostile)  # YAML reads JSON's escapes back into the raw characters
    out = tmp_path / "run"
    done = cli_runner.invoke(cli, ["run", str(repo / "scenarios" / "quickstart.yaml"), "--out", str(out),
                                   "--bag", "mcap",
                                   "--set", f"backend={{use: scripted, options: {{responses: [{answer}]}}}}",
                                   "--set", "max_steps=2"])
    assert done.exit_code == 0, done.output
    bags = [p for p in (out / "bags").iterdir() if p.is_dir()]
    assert len(bags) == 1
    logs = [message.msg for topic, _, message in read_mcap(bags[0]) if topic == "/rosout" and message.name == "llm"]
    assert logs
    for text in logs:
        assert "\\x00" in text and "\\x1b[2J" in text and "<script>" in text  # text, shown as written
        assert "\x00" not in text and "\x1b" not in text
        assert "ABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789" not in text  # a key-shaped secret is masked


@pytest.mark.parametrize("name", ["&bag", "[bag", "'bag", "bag: x", "#bag"])
def test_a_bag_named_oddly_still_reads_back(tmp_path, name):
    """The bag is written in a hidden folder under its final name, then moved: metadata.yaml names
    its file as rosbags wrote it, whatever the name (review finding: text replacement broke YAML)."""
    from rosbags.highlevel import AnyReader

    from safeembodai_core.ros import messages
    from safeembodai_core.ros.bag_export import write_bag

    message = messages.build("std_msgs/msg/String", data="hello")
    bag = write_bag(tmp_path / name, [("/note", 1, message)], storage="mcap")
    with AnyReader([bag]) as reader:
        assert [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()] == ["hello"]
    assert sorted(p.name for p in tmp_path.iterdir()) == [name]  # nothing left aside


def test_a_corrupt_row_is_an_error_naming_what_could_not_be_read(bag_run, tmp_path):
    import shutil
    import subprocess
    import sys

    _, path, results, _ = bag_run
    copy = tmp_path / "run"
    shutil.copytree(path, copy)
    trial = results[0].spec.trial_id
    with sqlite3.connect(copy / "results.sqlite") as db:
        db.execute("update steps set record = '{\"step\": \"x\"}' where trial_id = ?", (trial,))
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "export", str(copy), "--trial", trial,
                           "--out", str(tmp_path / "bag")], capture_output=True, text=True)
    assert done.returncode == 1 and f"cannot read the steps of {trial}" in done.stderr
    assert "Traceback" not in done.stderr and not (tmp_path / "bag").exists()


def test_a_changed_attack_is_a_divergence(bag_run):
    from safeembodai_core.loop.replay import difference

    _, _, _, steps = bag_run
    record = next(r for records in steps.values() for r in records if r.attacks)
    forged = record.model_copy(update={"attacks": [a.model_copy(update={"payload": "other"}) for a in record.attacks]})
    assert difference(record, forged) == "the attacks injected differ"
    assert difference(record, record.model_copy(update={"instruction": "x"})).startswith("the instruction differs")
    assert difference(record, record) is None
