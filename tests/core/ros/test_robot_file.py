"""The robot file (``guard-node --robot``, ``guard-mcp --policy``): the shipped example reads into the
guard's types; an unknown key, a bad value, a missing body or a file that is no regular file is an
error naming the file, the line and the key."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

from safeembodai_core import Guard
from safeembodai_core.contracts.robot import RobotSpec
from safeembodai_core.ros import LaserScan, SensorMount, Twist, read_robot_file
from safeembodai_core.ros.robot_file import RobotFileError, parse_robot_file

EXAMPLE = Path(__file__).resolve().parents[3] / "docs" / "examples" / "robot.yaml"


def written(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "robot.yaml"
    path.write_text(text, encoding="utf-8")
    return path


def test_the_shipped_example_reads_into_the_guards_types():
    robot = read_robot_file(EXAMPLE)
    assert robot.robot_spec() == RobotSpec(radius_mm=pytest.approx(302.324, abs=1e-3), width_mm=340.0, length_mm=450.0,
                                           footprint_mm=((250.0, 170.0), (-200.0, 170.0), (-200.0, -170.0),
                                                         (250.0, -170.0)))
    assert robot.mount() == robot.mount("/scan") == SensorMount(x_mm=120.0)
    assert robot.scan_topic == "/scan" and robot.null_range() == "unknown"
    assert robot.velocity_smoother.max_velocity == (0.5, 0.0, 2.5)
    assert robot.velocity_smoother.max_decel == (-2.5, 0.0, -3.2)
    assert robot.cmd_vel_timeout_s == 0.5


def test_the_defaults_are_the_fail_closed_reading_nav2s_limits_and_diff_drives_timeout(tmp_path):
    robot = read_robot_file(written(tmp_path, "radius_mm: 220\n"))
    assert robot.robot_spec() == RobotSpec(radius_mm=220.0, width_mm=440.0, length_mm=440.0)
    assert list(robot.scans) == ["/scan"] and robot.null_range("/scan") == "unknown" and robot.mount() == SensorMount()
    smoother = robot.velocity_smoother  # nav2_velocity_smoother's own defaults
    assert (smoother.max_velocity, smoother.min_velocity) == ((0.5, 0.0, 2.5), (-0.5, 0.0, -2.5))
    assert (smoother.max_accel, smoother.max_decel) == ((2.5, 0.0, 3.2), (-2.5, 0.0, -3.2))
    assert robot.cmd_vel_timeout_s == 0.5 and robot.holonomic is False


def test_each_scan_source_says_how_its_nulls_are_read(tmp_path):
    robot = read_robot_file(written(tmp_path, """radius_mm: 170
holonomic: true
scans:
  /front/scan: {null_range: no_return, mount: {x_mm: 200, yaw_deg: 0}}
  /rear/scan: {mount: {x_mm: -200, yaw_deg: 180}}
"""))
    assert robot.scan_topic == "/front/scan" and robot.robot_spec().holonomic
    assert (robot.null_range("/front/scan"), robot.null_range("/rear/scan")) == ("no_return", "unknown")
    assert robot.mount("/rear/scan") == SensorMount(x_mm=-200.0, yaw_deg=180.0)
    with pytest.raises(RobotFileError, match="lists no scan source '/scan' \\(it lists /front/scan, /rear/scan\\)"):
        robot.mount("/scan")
    open_room = json.loads('{"angle_min": 0.0, "angle_increment": 0.5235987755982988, "range_min": 0.1, '
                           '"range_max": 10.0, "ranges": [null, null, null, null, null, null, null, null, null, '
                           'null, null, null]}')
    front = LaserScan.from_ros(open_room, robot.mount("/front/scan"), null_range=robot.null_range("/front/scan"))
    guard = Guard(robot=robot.robot_spec())
    assert guard.check_twist(Twist(0.1, 0.0), 0.5, lidar_mm=front).valid
    rear = LaserScan.from_ros(open_room, robot.mount("/rear/scan"), null_range=robot.null_range("/rear/scan"))
    assert not guard.check_twist(Twist(0.1, 0.0), 0.5, lidar_mm=rear).valid


@pytest.mark.parametrize("text, message", [
    ("radius_mm: 170\nradios_mm: 200\n", r"robot.yaml:2: radios_mm: Extra inputs are not permitted; did you mean "
                                         r"'radius_mm'\?"),
    ("radius_mm: 170\nscans:\n  /scan: {null_range: free}\n",
     r"robot.yaml:3: scans./scan.null_range: Input should be 'unknown' or 'no_return', got 'free'"),
    ("radius_mm: 170\nscans:\n  /scan:\n    mount: {x_mm: true}\n",
     r"robot.yaml:4: scans./scan.mount.x_mm: Input should be a valid number, got True"),
    ("radius_mm: '170'\n", r"robot.yaml:1: radius_mm: Input should be a valid number, got '170'"),
    ("radius_mm: 1" + "0" * 400 + "\n", r"robot.yaml:1: radius_mm: Input should be a valid number, got an integer"),
    ("radius_mm: .nan\n", r"robot.yaml:1: radius_mm: Input should be a finite number"),
    ("radius_mm: -5\n", r"robot.yaml:1: radius_mm: Input should be greater than 0"),
    ("holonomic: false\n", r"give the body as radius_mm or as footprint_mm"),
    ("radius_mm: 170\nfootprint_mm: [[1, 0], [0, 1], [-1, 0]]\n", r"exactly one of them"),
    ("footprint_mm: [[0, 0], [100, 100], [100, 0], [0, 100]]\n",
     r"robot.yaml:1: footprint_mm: Value error, footprint_mm is not a simple polygon"),
    ("radius_mm: 170\nscans:\n  scan: {}\n",
     r"robot.yaml:3: scans.scan: a scan source's topic must be a full ROS name"),
    ("radius_mm: 170\nvelocity_smoother:\n  max_decel: [2.5, 0.0, 3.2]\n",
     r"robot.yaml:3: velocity_smoother.max_decel: Value error, must be <= 0 on every axis"),
    ("radius_mm: 170\nvelocity_smoother:\n  smoothing_frequency: 20.0\n",
     r"robot.yaml:3: velocity_smoother.smoothing_frequency: Extra inputs are not permitted"),
    ("radius_mm: 170\ncmd_vel_timeout_s: 0\n", r"robot.yaml:2: cmd_vel_timeout_s: Input should be greater than 0"),
    ("radius_mm: 170\nradius_mm: 300\n", r"robot.yaml:2: radius_mm: key repeated \(first on line 1\)"),
    ("- radius_mm: 170\n", r"robot.yaml: a robot file must be a YAML mapping, got list"),
    ("radius_mm: [170\n", r"robot.yaml:2: not valid YAML"),
])
def test_a_bad_robot_file_is_an_error_naming_the_file_line_and_key(tmp_path, text, message):
    with pytest.raises(RobotFileError, match=message) as caught:
        read_robot_file(written(tmp_path, text))
    assert str(tmp_path / "robot.yaml") in str(caught.value)


def test_a_robot_file_that_is_no_regular_file_is_refused_unread(tmp_path):
    with pytest.raises(RobotFileError, match="no such robot file"):
        read_robot_file(tmp_path / "absent.yaml")
    os.mkfifo(tmp_path / "pipe.yaml")
    with pytest.raises(RobotFileError, match="pipe.yaml: cannot read the robot file: .* not a regular file"):
        read_robot_file(tmp_path / "pipe.yaml")
    with pytest.raises(RobotFileError, match="larger than"):
        read_robot_file(written(tmp_path, "radius_mm: 170\n" + "#" * 300_000))
    (tmp_path / "linked.yaml").symlink_to(EXAMPLE)  # as colcon --symlink-install leaves a config: followed
    assert read_robot_file(tmp_path / "linked.yaml").mount() == SensorMount(x_mm=120.0)


@pytest.mark.parametrize("key, axes", [("max_velocity", [51.0, 0.0, 1.0]), ("min_velocity", [-0.5, 0.0, -1e9]),
                                       ("max_accel", [1e4, 0.0, 1.0]), ("max_decel", [-1.0, 0.0, -1e300])])
def test_smoother_limits_beyond_any_base_are_refused(key, axes):
    """They bound what a guard lets through, and so the cost of judging it (issue 52, item 8)."""
    with pytest.raises(RobotFileError, match=f"velocity_smoother.{key}"):
        parse_robot_file(f"radius_mm: 170\nvelocity_smoother: {{{key}: {axes}}}\n", "robot.yaml")
