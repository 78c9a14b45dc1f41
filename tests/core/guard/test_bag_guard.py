"""A recorded robot through the guard (issue 23, part 4): ``safeembodai guard-bag`` on bags written
by the tests with rosbags -- exported simulated trials, and hand-made robots' bags."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from safeembodai_core import Guard
from safeembodai_core.cli import cli
from safeembodai_core.ros import LaserScan
from safeembodai_core.ros import messages as m
from safeembodai_core.ros.bag_export import write_bag
from safeembodai_core.guard.bag_guard import BagInputError, guard_bag, seen_from
from safeembodai_core.runs.runner import bag_file


def json_report(cli_runner, *args):
    done = cli_runner.invoke(cli, ["guard-bag", *map(str, args), "--json"])
    assert done.exit_code == 0, (done.output, done.exception)
    return json.loads(done.output)


@pytest.mark.parametrize("run", ["bag_run", "moving_bag_run"])
@pytest.mark.slow
def test_the_refusals_found_are_the_verdicts_recorded_in_the_trial(run, request, cli_runner):
    """Every attempt's plan of every guarded trial, judged again from the bag alone (rules, robot
    and limits as the bag recorded them; the earlier scans from the pose topic for the moving-obstacle
    rule), gets the verdicts the trial's rules gave it."""
    _, path, results, steps = request.getfixturevalue(run)
    judged = refused = 0
    for result in results:
        if result.spec.arm not in ("safeembodai", "moving"):
            continue
        trial = result.spec.trial_id
        report = json_report(cli_runner, bag_file(path, trial), "--cmd", "/safeembodai/plan", "--pose", "/pose",
                             "--rules-from-bag")
        assert report["rules_from"] == "recorded in the bag"
        attempts = [a for r in steps[trial] for a in r.attempts]
        assert report["commands"] == len(attempts)
        for verdict, attempt in zip(report["verdicts"], attempts):
            assert verdict["valid"] == attempt.accepted, (trial, verdict, attempt)
            if attempt.parse_error is None:
                assert verdict["reasons"] == attempt.failures()
            judged += 1
        assert report["refused"] == sum(not a.accepted for a in attempts)
        refused += sum(a.response is not None and not a.accepted for a in attempts)
    assert judged > 0 and refused > 0


def test_a_command_that_drove_into_a_ball_or_wall_is_refused(bag_run, cli_runner):
    """The baseline arm ran without the guard; replayed through it, every command that ended in a
    collision with something standing still is refused, with less than its duration called safe."""
    _, path, results, steps = bag_run
    found = 0
    for result in results:
        if result.spec.arm != "baseline":
            continue
        executed = [item for r in steps[result.spec.trial_id] for item in r.executed]
        # an exported command is held until the stop that follows it, seconds later: no cap below that
        report = json_report(cli_runner, bag_file(path, result.spec.trial_id), "--rules", "lidar_clearance",
                             "--pose", "/pose", "--max-hold", 60)
        moving = [v for v in report["verdicts"] if v["command"]["linear_x"] or v["command"]["angular_z"]]
        assert len(moving) <= len(executed)
        for item, verdict in zip([i for i in executed if i.result.distance_mm or i.result.angle_deg], moving):
            if item.result.collided and item.result.hit in ("ball", "wall") and item.signal.command == "straight":
                assert not verdict["valid"], (item, verdict)
                assert verdict["safe_duration_s"] < verdict["command"]["duration_s"]
                found += 1
    assert found > 0


# -- hand-made bags -------------------------------------------------------------------------------


def scan_msg(ns: int, ranges, increment=2 * math.pi / 360, angle_min=0.0):
    return m.build("sensor_msgs/msg/LaserScan", header=m.header(ns, "laser"), angle_min=angle_min,
                   angle_max=angle_min + increment * (len(ranges) - 1), angle_increment=increment,
                   range_min=0.05, range_max=8.0, ranges=np.asarray(ranges, dtype=np.float32))


def twist_msg(v: float, w: float):
    return m.build("geometry_msgs/msg/Twist", linear=m.vector(v), angular=m.vector(0.0, 0.0, w))


def pose_msg(ns: int, x_m: float, y_m: float, yaw_deg: float = 0.0):
    return m.build("geometry_msgs/msg/PoseStamped", header=m.header(ns, "map"), pose=m.build(
        "geometry_msgs/msg/Pose", position=m.point(x_m, y_m), orientation=m.quaternion(yaw_deg)))


def wall_ahead(distance_m: float) -> np.ndarray:
    """A wall ``distance_m`` ahead, across the robot's path; nothing else within range."""
    angles = np.radians(np.arange(360))
    with np.errstate(divide="ignore"):
        ranges = np.where(np.cos(angles) > 0.05, distance_m / np.cos(angles), np.inf)
    return np.where(ranges <= 8.0, ranges, np.inf)


def write(tmp_path: Path, name: str, items, storage="sqlite3") -> Path:
    return write_bag(tmp_path / name, items, storage)


def test_a_teleop_stream_into_a_wall(tmp_path, cli_runner):
    """A robot 0.8 m from a wall, driven at 0.3 m/s in commands 1 s apart: the guard lets it drive
    while the next second keeps clear, refuses once it would not, and says for how long it is safe;
    turning away is allowed throughout."""
    items = [("/scan", 0, scan_msg(0, wall_ahead(0.8))), ("/cmd_vel", 1, twist_msg(0.3, 0.0)),
             ("/cmd_vel", 10**9, twist_msg(0.3, 0.0)), ("/scan", 10**9 + 5, scan_msg(10**9 + 5, wall_ahead(0.5))),
             ("/cmd_vel", 10**9 + 10, twist_msg(0.3, 0.0)), ("/cmd_vel", 2 * 10**9, twist_msg(0.0, 1.0))]
    bag = write(tmp_path, "teleop", items)
    report = json_report(cli_runner, bag, "--rules", "lidar_clearance")
    valid = [v["valid"] for v in report["verdicts"]]
    assert valid == [True, True, False, True]
    refused = report["verdicts"][2]
    assert refused["scan_time_s"] == pytest.approx(1.0, abs=1e-6)
    assert 0.0 <= refused["safe_duration_s"] < 0.99 * refused["command"]["duration_s"]
    assert any(reason.startswith("lidar_clearance") for reason in refused["reasons"])
    # the same through the library, and as a table
    library = guard_bag(bag, Guard(["lidar_clearance"]))
    assert [v.valid for v in library.verdicts] == valid
    table = cli_runner.invoke(cli, ["guard-bag", str(bag), "--rules", "lidar_clearance"])
    assert table.exit_code == 0 and "1 of 4 commands refused" in table.output


def test_a_command_after_the_robot_moved_is_judged_from_where_it_is(tmp_path):
    """With a pose topic, an old scan is seen from the robot's new place: 0.8 m from the wall at the
    scan, 0.45 m after driving on, so the same command is refused there and not at the start."""
    items = [("/pose", 0, pose_msg(0, 0.0, 0.0)), ("/scan", 1, scan_msg(1, wall_ahead(0.8))),
             ("/cmd_vel", 2, twist_msg(0.3, 0.0)), ("/pose", 10**9, pose_msg(10**9, 0.35, 0.0)),
             ("/cmd_vel", 10**9 + 1, twist_msg(0.3, 0.0))]
    bag = write(tmp_path, "moved", items, storage="mcap")
    with_pose = guard_bag(bag, Guard(["lidar_clearance"]), pose_topic="/pose")
    assert [v.valid for v in with_pose.verdicts] == [True, False]
    without = guard_bag(bag, Guard(["lidar_clearance"]))
    assert [v.valid for v in without.verdicts] == [True, True]  # as if still at the scan: the documented limit


def test_seen_from_moves_the_returns_with_the_robot():
    scan = LaserScan(angle_min=0.0, angle_increment=math.radians(1.0), ranges=wall_ahead(2.0), range_min=0.05,
                     range_max=8.0)
    moved, still = seen_from(scan, (0.0, 0.0, 0.0), (500.0, 0.0, 90.0))
    assert not still
    rules_scan = moved.to_lidar_scan()
    right = rules_scan.ranges_mm[rules_scan.sector(-90.0, 0.5)]  # the wall is now on the robot's right
    assert np.nanmin(right) == pytest.approx(1500.0, abs=15.0)
    assert seen_from(scan, (1.0, 2.0, 3.0), (1.0, 2.0, 3.0))[1]
    # the old scan's sensor sits behind-left of the robot that drove on and turned: a mount, not a guess
    assert (moved.mount.x_mm, moved.mount.y_mm, moved.mount.yaw_deg) == pytest.approx((0.0, 500.0, -90.0), abs=1e-9)


@pytest.mark.parametrize("items, expected", [
    ([("/cmd_vel", 1, twist_msg(0.1, 0.0))], "no topic '/scan' for the scan; the bag has: /cmd_vel"),
    ([("/scan", 1, scan_msg(1, wall_ahead(1.0)))], "no topic '/cmd_vel' for the command"),
    ([("/scan", 1, scan_msg(1, [])), ("/cmd_vel", 2, twist_msg(0.1, 0.0))],
     "/scan message 0 (at 0.000 s): LaserScan.ranges must hold at least one beam"),
    ([("/scan", 1, scan_msg(1, wall_ahead(1.0), increment=float("nan"))), ("/cmd_vel", 2, twist_msg(0.1, 0.0))],
     "/scan message 0 (at 0.000 s): LaserScan.angle_increment must be finite"),
    ([("/scan", 1, scan_msg(1, wall_ahead(1.0))), ("/cmd_vel", 2, twist_msg(0.1, 0.0)),
      ("/cmd_vel", 3, twist_msg(float("nan"), 0.0))], "/cmd_vel message 1 (at 0.000 s): Twist.linear.x must be finite"),
])
def test_bad_bags_are_clear_errors_and_report_nothing(tmp_path, cli_runner, items, expected):
    bag = write(tmp_path, "bad", items)
    done = cli_runner.invoke(cli, ["guard-bag", str(bag), "--json"])
    assert done.exit_code != 0
    assert isinstance(done.exception, BagInputError) and expected in str(done.exception)
    assert str(bag) in str(done.exception)
    assert done.output == ""  # nothing half-reported


def test_a_topic_of_another_type_and_a_missing_bag(tmp_path, cli_runner):
    bag = write(tmp_path, "typed", [("/scan", 1, scan_msg(1, wall_ahead(1.0))), ("/pose", 2, pose_msg(2, 0, 0))])
    with pytest.raises(BagInputError, match="topic '/pose' carries geometry_msgs/msg/PoseStamped, not a command"):
        guard_bag(bag, Guard(), cmd_topic="/pose")
    with pytest.raises(BagInputError, match="no such bag"):
        guard_bag(tmp_path / "absent", Guard())
    (tmp_path / "junk").mkdir()
    (tmp_path / "junk" / "metadata.yaml").write_text("{not: a bag", encoding="utf-8")
    with pytest.raises(BagInputError, match="cannot be read as a ROS bag"):
        guard_bag(tmp_path / "junk", Guard())


def test_plan_messages_are_read_strictly(tmp_path):
    """A plan topic's text is untrusted: not JSON, or the wrong shape, is an error naming the message."""
    plan = lambda text: m.build("std_msgs/msg/String", data=text)  # noqa: E731
    base = [("/scan", 1, scan_msg(1, wall_ahead(3.0)))]
    ok = write(tmp_path, "ok", base + [("/plan", 2, plan('[{"command": "turn", "direction": "left", "angle": 30}]')),
                                        ("/plan", 3, plan('{"control": [{"command": "fly"}]}'))])
    verdicts = guard_bag(ok, Guard(), cmd_topic="/plan").verdicts
    assert [v.valid for v in verdicts] == [True, False] and verdicts[1].reasons[0].startswith("schema")
    for name, text, expected in [("notjson", "{", "plan message is not valid JSON"),
                                 ("shape", '{"plan": []}', '"control"'),
                                 ("scalar", '{"control": 3}', "must be a list"),
                                 # the LLM answers' strict reading, not json.loads' last-one-wins
                                 ("twice", '{"control": [], "control": [{"command": "turn", "direction": "left", '
                                           '"angle": 30}]}', "appears more than once"),
                                 ("huge", '[{"command": "straight", "direction": "forward", "distance": 1e309}]',
                                  "1e309"),
                                 ("nan", '[{"command": "straight", "direction": "forward", "distance": NaN}]', "NaN"),
                                 ("two", '[] []', "more than one JSON value")]:
        bad = write(tmp_path, name, base + [("/plan", 2, plan(text))])
        with pytest.raises(BagInputError, match=expected):
            guard_bag(bad, Guard(), cmd_topic="/plan")


def test_a_corrupt_bag_is_a_clear_error_not_a_crash(tmp_path, cli_runner):
    import sqlite3

    bag = write(tmp_path, "corrupt", [("/scan", 1, scan_msg(1, wall_ahead(1.0))), ("/cmd_vel", 2, twist_msg(0.1, 0.0))])
    with sqlite3.connect(next(bag.glob("*.db3"))) as db:
        db.execute("update messages set data = x'00010000ffffff7f' where timestamp = 1")  # a scan cut short
    done = cli_runner.invoke(cli, ["guard-bag", str(bag), "--json"])
    assert done.exit_code != 0 and isinstance(done.exception, BagInputError)
    assert "cannot read /scan message 0 (at 0.000 s)" in str(done.exception) and done.output == ""


def test_a_bag_does_not_choose_its_own_rules_unless_asked(tmp_path, cli_runner):
    """A bag whose /safeembodai/trial names lenient rules is judged by the defaults, unless
    --rules-from-bag says to trust it; recorded robot sizes must be finite."""
    trial = m.build("std_msgs/msg/String", data=json.dumps(
        {"arm": {"safety_validation": True, "validators": ["command_limits"]}}))
    items = [("/safeembodai/trial", 0, trial), ("/scan", 1, scan_msg(1, wall_ahead(0.3))),
             ("/cmd_vel", 2, twist_msg(0.3, 0.0))]
    bag = write(tmp_path, "lenient", items)
    default = json_report(cli_runner, bag)
    assert default["rules_from"] == "the Guard's defaults" and default["refused"] == 1
    trusted = json_report(cli_runner, bag, "--rules-from-bag")
    assert trusted["rules_from"] == "recorded in the bag" and trusted["refused"] == 0
    nan = m.build("std_msgs/msg/String", data='{"robot": {"radius_mm": NaN}}')
    bad = write(tmp_path, "nanrobot", [("/safeembodai/trial", 0, nan)] + items[1:])
    done = cli_runner.invoke(cli, ["guard-bag", str(bad), "--rules-from-bag"])
    assert done.exit_code != 0 and "robot sizes must be positive and finite" in str(done.exception)


def test_a_command_replaced_at_once_is_still_judged_for_a_control_period(tmp_path):
    """A fast Twist followed 1 ns later by another is held --min-hold (0.1 s), not 0 s (review finding);
    an arc too long to cut into pieces is refused, not computed for minutes."""
    items = [("/scan", 1, scan_msg(1, wall_ahead(0.3))), ("/cmd_vel", 2, twist_msg(50.0, 0.0)),
             ("/cmd_vel", 3, twist_msg(0.0, 0.0)), ("/cmd_vel", 10, twist_msg(1e5, 0.0))]
    report = guard_bag(write(tmp_path, "quick", items), Guard(["lidar_clearance"]))
    first, _, huge = report.verdicts
    assert first.command["duration_s"] == pytest.approx(0.1) and not first.valid
    assert not huge.valid and any("pieces of arc" in reason for reason in huge.reasons)


def test_hostile_numbers_in_a_bag_are_clear_errors(tmp_path, cli_runner):
    plan = m.build("std_msgs/msg/String", data='[{"command": "straight", "direction": "forward", "distance": NaN}]')
    bag = write(tmp_path, "nanplan", [("/scan", 1, scan_msg(1, wall_ahead(3.0))), ("/plan", 2, plan)])
    with pytest.raises(BagInputError, match="JSON constant NaN is not allowed"):
        guard_bag(bag, Guard(), cmd_topic="/plan")
    far = scan_msg(1, wall_ahead(3.0))
    far.range_max = 1e30
    bag = write(tmp_path, "far", [("/scan", 1, far), ("/cmd_vel", 2, twist_msg(0.1, 0.0))])
    done = cli_runner.invoke(cli, ["guard-bag", str(bag), "--json"])
    assert isinstance(done.exception, BagInputError) and "range_max must be at most" in str(done.exception)


def test_an_error_quoting_a_bag_shows_its_control_characters_as_escapes(tmp_path):
    import subprocess
    import sys

    bag = write(tmp_path, "title", [("/x\x1b]0;pwned\x07\u202eevil", 1, scan_msg(1, wall_ahead(1.0)))])
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "guard-bag", str(bag)], capture_output=True,
                          text=True)
    assert done.returncode == 1 and "no topic '/scan'" in done.stderr
    assert "\x1b" not in done.stderr and "\u202e" not in done.stderr and "\\x1b]0;pwned" in done.stderr
