"""The picture cache: a view already drawn in this process, from the same room and poses, comes back
with the same pixels; any other view is drawn."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from safeembodai_core.models import Straight, Turn
from safeembodai_plugins.environments.pybullet_rooms import picture_cache
from safeembodai_plugins.environments.pybullet_rooms.picture_cache import BUDGET_VARIABLE, PictureCache

COMMANDS = [
    Turn(command="turn", direction="left", angle=40.0),
    Straight(command="straight", direction="forward", distance=350.0),
    Turn(command="turn", direction="right", angle=75.0),
    Straight(command="straight", direction="backward", distance=200.0),
]


@pytest.fixture
def pictures(monkeypatch) -> PictureCache:
    """A fresh cache of the default budget for the test (the process's own is left as it was)."""
    cache = PictureCache(max_bytes=picture_cache.MAX_BYTES)
    monkeypatch.setattr(picture_cache, "PICTURES", cache)
    return cache


def trial_pictures(env, seed: int) -> list[np.ndarray]:
    """Every picture of a trial of :data:`COMMANDS` (the Labbots move through each think time)."""
    seen = [env.reset(seed).camera]
    for signal in COMMANDS:
        env.execute(signal)
        seen.append(env.observe().camera)
    return seen


def drawn(env, xy, heading: float, monkeypatch) -> np.ndarray:
    """The picture drawn by TinyRenderer itself, the cache off."""
    with monkeypatch.context() as patch:
        patch.setattr(picture_cache, "PICTURES", PictureCache(max_bytes=0))
        return env.sensors.camera(xy, heading)


@pytest.mark.parametrize("kind", ["OF", "MO"])
def test_another_room_at_the_same_poses_gets_the_same_pictures_from_the_cache(make_env, pictures, monkeypatch, kind):
    first = trial_pictures(make_env(kind, think_time_s=1.5), 4)
    assert pictures.hits == 0 and pictures.misses == len(first)
    second_room = make_env(kind, think_time_s=1.5)
    second = trial_pictures(second_room, 4)
    assert pictures.hits == len(first)  # every picture of the second room's trial came from the cache
    for ours, theirs in zip(first, second):
        assert np.array_equal(ours, theirs)
    assert np.array_equal(second[-1], drawn(second_room, second_room.xy, second_room.heading, monkeypatch))


def test_a_picture_from_the_cache_is_the_callers_own(make_env, pictures):
    env = make_env("OF")
    kept = env.reset(2).camera  # drawn, and kept
    served = env.sensors.camera(env.xy, env.heading)
    served[:] = 0  # a caller that draws on its picture changes nobody else's
    again = env.sensors.camera(env.xy, env.heading)
    assert pictures.hits == 2 and np.array_equal(again, kept) and again.any()


def test_any_body_moved_by_a_hair_or_another_view_is_drawn_again(make_env, pictures):
    env = make_env("MO", think_time_s=1.5)
    env.reset(6)  # its picture is drawn and kept
    xy, heading = env.xy.copy(), env.heading
    assert (pictures.hits, pictures.misses) == (0, 1)
    swarm = env.swarm
    moved = swarm.xy.copy()
    moved[0, 0] += 1e-6  # a nanometre
    env.scene.place_labbots(moved, swarm.heading)
    env.sensors.camera(xy, heading)
    env.sensors.camera(xy, heading + 1e-9)
    env.sensors.camera(xy + np.array([1e-6, 0.0]), heading)
    assert (pictures.hits, pictures.misses) == (0, 4)
    env.sensors.camera(xy + np.array([1e-6, 0.0]), heading)
    env.scene.place_labbots(swarm.xy, swarm.heading)  # back where they were: the reset's picture again
    env.sensors.camera(xy, heading)
    assert (pictures.hits, pictures.misses) == (2, 4)


def test_rooms_built_otherwise_never_share_a_picture(make_env, pictures):
    wide, narrow = make_env("OF"), make_env("OF", camera_fov_deg=50.0)
    one, other = wide.reset(3).camera, narrow.reset(3).camera
    # the same layout and poses: only the camera's field differs
    assert np.array_equal(wide.xy, narrow.xy) and wide.heading == narrow.heading
    assert (pictures.hits, pictures.misses) == (0, 2) and not np.array_equal(one, other)


def test_the_least_recently_used_picture_goes_first_beyond_the_budget():
    noise = np.random.default_rng(0)
    pictures = {key: noise.integers(0, 255, (10, 10, 3), dtype=np.uint8) for key in (b"a", b"b", b"c", b"d")}
    one = PictureCache(max_bytes=10**6)
    one.put(b"a", pictures[b"a"])
    cache = PictureCache(max_bytes=3 * one.size_bytes)  # room for three (noise compresses alike)
    for key in (b"a", b"b"):
        cache.put(key, pictures[key])
    assert cache.get(b"a") is not None  # a is now the more recently used
    for key in (b"c", b"d"):
        cache.put(key, pictures[key])
    assert cache.size_bytes <= cache.max_bytes and len(cache) == 3
    assert cache.get(b"b") is None and np.array_equal(cache.get(b"d"), pictures[b"d"])
    assert PictureCache(max_bytes=100).enabled and not PictureCache(max_bytes=0).enabled
    tiny = PictureCache(max_bytes=10)
    tiny.put(b"a", pictures[b"a"])  # larger than the whole budget: not kept
    assert len(tiny) == 0 and tiny.size_bytes == 0


@pytest.mark.parametrize("value, budget", [("0", 0), ("2.5", int(2.5 * 2**20)), ("", picture_cache.MAX_BYTES)])
def test_the_budget_comes_from_the_environment(monkeypatch, value, budget):
    monkeypatch.setenv(BUDGET_VARIABLE, value)
    assert PictureCache().max_bytes == budget


@pytest.mark.parametrize("value", ["lots", "-1", "nan", "inf"])
def test_a_budget_that_is_not_a_size_is_refused_naming_the_variable(value):
    code = "import safeembodai_plugins.environments.pybullet_rooms.picture_cache"
    env = {"PATH": "/usr/bin:/bin", BUDGET_VARIABLE: value}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env)
    assert out.returncode != 0 and BUDGET_VARIABLE in out.stderr and repr(value) in out.stderr
