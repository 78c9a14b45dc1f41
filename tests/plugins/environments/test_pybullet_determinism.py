"""Determinism: the same seed and commands give bit-identical worlds, scans, images and paths,
whatever ran before, in one process (separate physics clients) or in another. Every picture is
drawn here (no picture cache): the rendering's own determinism is what is tested."""

from __future__ import annotations

import pytest
import hashlib
import subprocess
import sys

import numpy as np

from safeembodai_core.models import Straight, Turn

COMMANDS = [
    Turn(command="turn", direction="left", angle=40.0),
    Straight(command="straight", direction="forward", distance=350.0),
    Turn(command="turn", direction="right", angle=75.0),
    Straight(command="straight", direction="forward", distance=399.0),
    Straight(command="straight", direction="backward", distance=200.0),
] * 2
OPTIONS = {"think_time_s": 1.5}
pytestmark = pytest.mark.usefixtures("no_picture_cache")


def record(env, seed: int) -> list:
    """Everything observable about a trial: readings, results, poses, Labbot positions."""
    observation = env.reset(seed)
    out = [observation.camera.tobytes(), observation.lidar.ranges_mm.tobytes(), observation.pose]
    for signal in COMMANDS:
        result = env.execute(signal)
        observation = env.observe()
        out += [result, observation.camera.tobytes(), observation.lidar.ranges_mm.tobytes(), observation.pose,
                observation.truth, env.swarm.xy.tobytes(), env.sim_time_s]
    return out


def digest(trace: list) -> str:
    return hashlib.sha256(repr(trace).encode()).hexdigest()


def test_two_environments_in_one_process_agree_bit_for_bit(make_env):
    a, b = make_env("MO", **OPTIONS), make_env("MO", **OPTIONS)
    a.reset(11)
    b.reset(11)
    for signal in COMMANDS:  # interleaved calls on two physics clients
        assert a.execute(signal) == b.execute(signal)
        first, second = a.observe(), b.observe()
        assert np.array_equal(first.camera, second.camera)
        assert first.lidar.ranges_mm.tobytes() == second.lidar.ranges_mm.tobytes()
        assert first.pose == second.pose and first.truth == second.truth
        assert a.swarm.xy.tobytes() == b.swarm.xy.tobytes()


def test_a_trial_does_not_depend_on_what_ran_before(make_env):
    fresh, used = make_env("MO", **OPTIONS), make_env("MO", **OPTIONS)
    record(used, 5)
    record(used, 3)
    assert record(fresh, 11) == record(used, 11)


def test_different_seeds_give_different_rooms(make_env):
    env = make_env("MO")
    first = env.reset(1)
    layout = (env.can_xy.copy(), env.balls_xy.copy())
    second = env.reset(2)
    assert first.pose != second.pose
    assert not np.array_equal(layout[0], env.can_xy) and not np.array_equal(layout[1], env.balls_xy)


@pytest.mark.slow
def test_another_process_sees_the_same_trial(make_env):
    code = "\n".join([
        "import importlib.util, sys",
        "spec = importlib.util.spec_from_file_location('determinism', sys.argv[1])",
        "test = importlib.util.module_from_spec(spec)",
        "spec.loader.exec_module(test)",
        "from safeembodai_core.plugin.manager import load_plugins",
        "env = load_plugins(environ={}).registry.build('environment', 'MO', test.OPTIONS)",
        "print(test.digest(test.record(env, 11)))",
        "env.close()",
    ])
    out = subprocess.run([sys.executable, "-c", code, __file__], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == digest(record(make_env("MO", **OPTIONS), 11))
