"""Every trial's picture says what it shows: a key of its marks (robot, start, target, obstacles,
Labbots, collision) drawn by the worlds, and the core's caption above it (trial id, arm, condition,
a simulated pilot's note). Text drawn is read off ``cv2.putText``, not off pixels."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from safeembodai_plugins.environments.pybullet_rooms.picture import SIZE_PX
from safeembodai_plugins.environments.topdown import TopDownScene, key_entries, key_height

from safeembodai_core.models import Outcome, TrialSpec
from safeembodai_core.plugin.refs import ComponentRef
from safeembodai_core.runs.captions import caption_lines, captioned
from safeembodai_core.scenario.describe import describe_ref
from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
from safeembodai_core.testing import answer, inline_plugins, straight, tiny_scenario, turn

ALWAYS = ["robot's path", "start", "robot at the end", "can (target), reach circle"]


@pytest.fixture
def drawn(monkeypatch):
    """Every text ``cv2.putText`` writes from now on."""
    texts: list[str] = []
    real = cv2.putText

    def spy(image, text, *args, **kwargs):
        texts.append(text)
        return real(image, text, *args, **kwargs)

    monkeypatch.setattr(cv2, "putText", spy)
    return texts


def decode(png: bytes) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(png, np.uint8), cv2.IMREAD_COLOR)


def test_a_room_with_labbots_draws_a_key_of_every_mark(make_env, moves, drawn):
    env = make_env("MO")
    env.reset(0)
    poses = [env.pose()]
    env.execute(moves.go(200))
    poses.append(env.pose())
    picture = decode(env.trajectory_png(poses, Outcome.TIMEOUT))
    assert drawn[-7:] == ALWAYS + ["soccer ball", "Labbot at the end", "Labbot track"]
    assert picture.shape[1] == SIZE_PX and picture.shape[0] > SIZE_PX  # the key below the room's square


def test_flatland_draws_its_key_and_a_collision_is_in_it(make_env, drawn):
    env = make_env("flatland", obstacles=3)
    env.reset(2)
    env.trajectory_png([env.pose()], None)
    assert drawn[-5:] == ALWAYS + ["obstacle"]
    scene = TopDownScene(title="t", room_mm=4000, can_xy=(1000, 1000), can_radius_mm=33, reach_mm=450,
                         robot_radius_mm=170, collision_xy=(2000, 2000))
    assert [label for _, label in key_entries(scene)] == ALWAYS + ["collision"]
    assert key_height(scene) > 0


@pytest.mark.parametrize("backend, note", [("scripted", "scripted answers (scripted): not a measurement of an LLM"),
                                           ("mock", "simulated pilot (mock): not a measurement of an LLM"),
                                           ("local", None)])
def test_the_caption_names_the_trial_and_a_simulated_pilot(backend, note):
    spec = TrialSpec(trial_id="MO/safeembodai/attack/3", environment="MO", arm="safeembodai", condition="attack",
                     index=3, seed=1)
    options = {"responses": ["x"]} if backend == "scripted" else {}
    lines = caption_lines(spec, describe_ref(ComponentRef(use=backend, options=options), inline_plugins()).simulated)
    assert lines[0] == "trial MO/safeembodai/attack/3: arm safeembodai, condition attack"
    assert lines[1:] == ([note] if note else [])


def test_the_runner_captions_every_saved_picture(tmp_path, drawn):
    plugins = inline_plugins()
    scenario = tiny_scenario([answer(turn(30), straight(200))], max_steps=2, registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins, run_dir=tmp_path, save_trajectories=True)
    try:
        spec = trial_spec(scenario, "flatland", "arm", "condition", 0)
        result = runner.run(spec)
        bare = decode(runner.environment("flatland").trajectory_png(result.trajectory, result.outcome))
    finally:
        runner.close()
    assert "trial flatland/arm/condition/0: arm arm, condition condition" in drawn
    assert "scripted answers (scripted): not a measurement of an LLM" in drawn
    saved = decode(runner.trajectory_path(spec.trial_id).read_bytes())
    assert saved.shape[1] == bare.shape[1] and saved.shape[0] > bare.shape[0]  # the caption above the picture
    assert np.array_equal(saved[-bare.shape[0]:], bare)  # the environment's picture itself, untouched


def test_a_third_party_picture_is_captioned_or_kept_as_drawn():
    assert captioned(b"not a picture", ["trial x"]) == b"not a picture"
    ok, rgba = cv2.imencode(".png", np.zeros((40, 60, 4), dtype=np.uint8))  # transparent: over white
    image = cv2.imdecode(np.frombuffer(captioned(rgba.tobytes(), ["trial x", "note"]), np.uint8), cv2.IMREAD_COLOR)
    assert image.shape[1] == 60 and image.shape[0] > 40 and (image[-40:] == 255).all()
