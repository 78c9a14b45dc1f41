"""Fixtures for the pybullet rooms: a registry, an environment factory that closes what it built,
and ``moves``: helpers that build control signals and turn the robot to a bearing or heading.
(Tests run with ``--import-mode=importlib``, so helpers are handed out as a fixture.)"""

from __future__ import annotations

import math
from types import SimpleNamespace

import pytest

from safeembodai_core.models import Straight, Turn


@pytest.fixture
def no_picture_cache(monkeypatch):
    """The camera draws every picture itself (no process-wide picture cache): for tests of the
    rendering's own determinism, which a picture served from the cache would answer by itself."""
    from safeembodai_plugins.environments.pybullet_rooms import picture_cache

    monkeypatch.setattr(picture_cache, "PICTURES", picture_cache.PictureCache(max_bytes=0))


@pytest.fixture(scope="session")
def registry():
    from safeembodai_core.plugin.manager import load_plugins

    return load_plugins(environ={}).registry


@pytest.fixture
def make_env(registry):
    """``make_env("MO", think_time_s=2)`` builds an environment; every one is closed after the test."""
    built = []

    def make(kind: str = "OF", **options):
        env = registry.build("environment", kind, options)
        built.append(env)
        return env

    yield make
    for env in built:
        env.close()


def go(distance: float) -> Straight:
    return Straight(command="straight", direction="forward" if distance > 0 else "backward", distance=abs(distance))


def rotate(angle: float) -> Turn:
    return Turn(command="turn", direction="left" if angle > 0 else "right", angle=abs(angle))


def turn_by(env, angle: float) -> None:
    """Turn ``angle`` degrees (CCW positive) in pieces below the 90-degree contract."""
    while abs(angle) > 1e-9:
        piece = math.copysign(min(abs(angle), 80.0), angle)
        env.execute(rotate(piece))
        angle -= piece


def drive(env, distance: float) -> list:
    """Drive ``distance`` mm (negative: backward) in pieces below the 400 mm contract; the results."""
    results = []
    while abs(distance) > 1e-9:
        piece = math.copysign(min(abs(distance), 390.0), distance)
        results.append(env.execute(go(piece)))
        if results[-1].stopped:
            break
        distance -= piece
    return results


def face(env, heading_deg: float) -> None:
    """Turn the robot to the world heading ``heading_deg``."""
    turn_by(env, (heading_deg - env.pose().heading_deg + 180.0) % 360.0 - 180.0)


@pytest.fixture(scope="session")
def moves():
    """``moves.go(300)``, ``moves.rotate(-30)``, ``moves.turn_by(env, 120)``, ``moves.drive(env, 900)``,
    ``moves.face(env, 90)``."""
    return SimpleNamespace(go=go, rotate=rotate, turn_by=turn_by, drive=drive, face=face)


@pytest.fixture
def reference_room(monkeypatch):
    """The rooms without their shortcuts (issue 51's cost cuts), as a reference to compare them with:
    every contact check and every Labbot sensor ray asked of Bullet, every placement sent at once,
    every ball rendered, and each tick's stream made by ``np.random.default_rng([seed, tick])``."""
    import numpy as np

    from safeembodai_plugins.environments.pybullet_rooms import scene, sensors, streams

    monkeypatch.setattr(scene, "CLEAR_MM", math.inf)
    monkeypatch.setattr(sensors, "RAY_SLACK_MM", math.inf)
    monkeypatch.setattr(sensors, "VIEW_SLACK_MM", math.inf)
    monkeypatch.setattr(streams.TickStreams, "generator", lambda self, tick: np.random.default_rng([self.seed, tick]))
    for name in ("place", "place_robot", "place_labbots", "place_statics"):
        placed = getattr(scene.Scene, name)

        def at_once(self, *args, placed=placed, **kwargs):
            placed(self, *args, **kwargs)
            self.flush()

        monkeypatch.setattr(scene.Scene, name, at_once)
