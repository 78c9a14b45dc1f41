"""What users see: no pybullet chatter on stdout/stderr, the trajectory picture, and a tiny
scenario running end to end on ``MO`` with the scripted backend."""

from __future__ import annotations

import pytest
import os
import subprocess
import sys

import cv2
import numpy as np
from safeembodai_plugins.environments.pybullet_rooms.picture import MARGIN_PX, SIZE_PX
from safeembodai_plugins.environments.pybullet_rooms.scene import WALL_THICKNESS_MM

from safeembodai_core.models import Outcome, Pose
from safeembodai_core.testing import answer, straight, tiny_scenario, turn


def decode(png: bytes) -> np.ndarray:
    assert png[:8] == b"\x89PNG\r\n\x1a\n"
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)


def test_no_pybullet_output_reaches_stdout_or_stderr(make_env, moves, capfd):
    env = make_env("MO", think_time_s=1.0)
    env.reset(0)
    env.execute(moves.go(300))
    env.observe()
    env.outcome()
    env.trajectory_png([env.pose()], None)
    env.close()
    out, err = capfd.readouterr()
    assert out == "" and err == ""


def test_silenced_swallows_c_level_writes_even_when_buffered():
    code = "\n".join([
        "import ctypes, os",
        "from safeembodai_plugins.environments.pybullet_rooms.quiet import silenced",
        "libc = ctypes.CDLL(None)",
        "with silenced():",
        "    libc.printf(b'buffered C chatter\\n')",  # sits in the C buffer: stdout is a pipe here
        "    os.write(1, b'raw fd 1\\n')",
        "    os.write(2, b'raw fd 2\\n')",
        "libc.fflush(None)",  # anything still buffered would surface now, after the block
        "print('after', flush=True)",
    ])
    environ = {k: v for k, v in os.environ.items() if k != "PYTHONUNBUFFERED"}  # keep C stdio buffered
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, env=environ)
    assert done.stdout == "after\n" and done.stderr == ""


def test_a_fresh_process_prints_nothing_not_even_the_build_banner():
    code = ("from safeembodai_core.plugin.manager import load_plugins; "
            "env = load_plugins(environ={}).registry.build('environment', 'SO', {}); env.reset(1); env.close()")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert done.stdout == "" and done.stderr == ""


def test_trajectory_picture_shows_room_path_and_outcome(make_env, moves):
    env = make_env("MO")
    env.reset(0)
    poses = [env.pose()]
    for _ in range(3):
        scan = env.observe().lidar
        moves.turn_by(env, float(scan.angles_deg[int(np.argmax(scan.ranges_mm))]))  # the clearest way
        assert not env.execute(moves.go(250)).stopped
        poses.append(env.pose())
    running = decode(env.trajectory_png(poses, None))
    completed = decode(env.trajectory_png(poses, Outcome.COMPLETED))
    assert running.shape[1:] == (SIZE_PX, 3) and running.shape[0] > SIZE_PX  # the room's square, the key below
    assert not np.array_equal(running, completed)  # the outcome is written on it
    no_path = decode(env.trajectory_png([poses[0]], None))
    scale = (SIZE_PX - 2 * MARGIN_PX) / (env.options.room_mm + 2 * WALL_THICKNESS_MM)
    for a, b in zip(poses, poses[1:]):  # the middle of each leg is painted orange, and only with the path
        col = int(round(MARGIN_PX + ((a.x_mm + b.x_mm) / 2 + WALL_THICKNESS_MM) * scale))
        row = int(round(SIZE_PX - MARGIN_PX - ((a.y_mm + b.y_mm) / 2 + WALL_THICKNESS_MM) * scale))
        blue_, green, red = (int(v) for v in running[row, col])
        assert red > 200 and blue_ < 100 and 80 < green < 200, (row, col, running[row, col])
        assert tuple(no_path[row, col]) != tuple(running[row, col])
    blue = np.all(running == (190, 90, 40), axis=-1).sum()  # Labbots
    assert blue > 50


def test_tiny_scenario_runs_end_to_end_on_MO_and_draws_its_trajectory(tmp_path):
    from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
    from safeembodai_core.testing import inline_plugins

    plugins = inline_plugins()
    responses = [answer(turn(45), straight(300)), answer(straight(250))]
    scenario = tiny_scenario(responses, environment={"use": "MO", "options": {"think_time_s": 1.0}},
                             max_steps=4, registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins, run_dir=tmp_path)
    try:
        spec = trial_spec(scenario, "MO", "arm", "condition", 0)
        result = runner.run(spec)
        picture = runner.environment("MO").trajectory_png(result.trajectory, result.outcome)
    finally:
        runner.close()
    assert result.outcome in (Outcome.TIMEOUT, Outcome.INTERRUPTED, Outcome.COMPLETED)
    assert result.outcome is not Outcome.ERROR, result.detail
    assert len(result.trajectory) >= 3 and result.distance_mm > 0
    assert all(isinstance(p, Pose) for p in result.trajectory)
    assert decode(picture).shape[1] == SIZE_PX


@pytest.mark.slow
def test_cli_run_on_MO_writes_a_trajectory_picture_and_no_pybullet_chatter(tmp_path):
    import yaml

    scenario = {
        "name": "mo-cli", "trials": 1, "max_steps": 3, "environments": [{"use": "MO"}],
        "backend": {"use": "scripted", "options": {"responses": [answer(turn(30), straight(200))]}},
        "arms": {"baseline": {}}, "conditions": {"none": {"attackers": []}},
    }
    path = tmp_path / "mo.yaml"
    path.write_text(yaml.safe_dump(scenario))
    out = tmp_path / "out"
    cli = [sys.executable, "-c", "from safeembodai_core.cli import main; main()"]
    done = subprocess.run([*cli, "run", str(path), "--out", str(out)], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert decode((out / "trajectory.png").read_bytes()).shape[1] == SIZE_PX
    for stream in (done.stdout, done.stderr):
        assert "pybullet" not in stream and "b3Printf" not in stream
