"""Helpers for the backend tests: prompts built by the real perception and prompt builder."""

from __future__ import annotations

import numpy as np


def make_prompt(plugins, observation, *, instruction="Find the red can in the room and approach it.",
                perception="images", prefix=None, reference=None, failures=(), step=1):
    """The prompt the real perception and jinja builder make of ``observation``."""
    from safeembodai_core.models import PromptRequest

    seeing = plugins.registry.build("perception", perception, {})
    builder = plugins.registry.build("prompt_builder", "jinja", {})
    request = PromptRequest(instruction=instruction, modalities=seeing.perceive(observation), step=step,
                            security_prefix=prefix, reference_state=reference, failures=tuple(failures))
    return builder.build(request)


def flatland_observation(plugins, seed=0, turn_to_can=None, obstacles=0):
    """A flatland observation; with ``turn_to_can`` the robot first turns so the can sits at that bearing."""
    from safeembodai_core.models import Turn

    world = plugins.registry.build("environment", "flatland", {"obstacles": obstacles})
    observation = world.reset(seed)
    if turn_to_can is not None:
        rotate = observation.truth.target_bearing_deg - turn_to_can
        while abs(rotate) > 1e-6:
            step = float(np.clip(rotate, -89.0, 89.0))
            world.execute(Turn(command="turn", direction="left" if step > 0 else "right", angle=abs(step)))
            rotate -= step
        observation = world.observe()
    return world, observation


def one_trial_steps(plugins, data, arm, condition="no_attack", environment="flatland"):
    """Trial 0 of the scenario ``data`` (a dict, as YAML would give it) in one cell: its step records."""
    import yaml

    from safeembodai_core.runner import ScenarioRunner, trial_spec
    from safeembodai_core.scenario import parse_scenario

    scenario = parse_scenario(yaml.safe_dump(data), "<test>", registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, environment, arm, condition, 0)
        runner.run(spec)
        return runner.state.steps(spec.trial_id)
    finally:
        runner.close()
