"""Helpers for the backend tests: prompts built by the real perception and prompt builder."""

from __future__ import annotations

import numpy as np


def make_prompt(plugins, observation, *, instruction="Find the red can in the room and approach it.",
                perception="images", prefix=None, reference=None, failures=(), step=1):
    """The prompt the real perception and jinja builder make of ``observation``. ``failures``: lines,
    or ``(line, Refusal)`` pairs (:func:`refused`) when the refusals go along as data as the loop sends them."""
    from safeembodai_core.models import PromptRequest

    seeing = plugins.registry.build("perception", perception, {})
    builder = plugins.registry.build("prompt_builder", "jinja", {})
    pairs = [item if isinstance(item, tuple) else (item, None) for item in failures]
    refusals = tuple(r for _, r in pairs if r is not None)
    request = PromptRequest(instruction=instruction, modalities=seeing.perceive(observation), step=step,
                            security_prefix=prefix, reference_state=reference,
                            failures=tuple(line for line, _ in pairs),
                            refusals=refusals if len(refusals) == len(pairs) else ())
    return builder.build(request)


def signals_of(text):
    """``"turn left 12 deg, straight forward 399 mm"`` as control signals (the tests' shorthand)."""
    from safeembodai_core.models import Straight, Turn

    signals = []
    for part in filter(None, (p.strip() for p in text.split(","))):
        command, direction, value, _ = part.split()
        signals.append(Turn(command="turn", direction=direction, angle=float(value)) if command == "turn"
                       else Straight(command="straight", direction=direction, distance=float(value)))
    return signals


def refused(plan, signal, reason, rule="moving_obstacles", attempt=1, advice=None):
    """A failure line as the loop writes it and the same refusal as data: ``plan`` refused (shorthand,
    :func:`signals_of`; "" for none), on ``signal`` (from 1; None for none), with ``advice`` (an ``Advice``)."""
    from safeembodai_core.models import Refusal

    where = "" if signal is None else f" (signal {signal})"
    shown = f" (refused plan: {plan})" if plan else ""
    line = f"attempt {attempt}{shown}: {rule}{where}: {reason}"
    return line, Refusal(attempt=attempt, plan=signals_of(plan), rule=rule,
                         signal_index=None if signal is None else signal - 1, advice=advice)


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

    from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
    from safeembodai_core.scenario import parse_scenario

    scenario = parse_scenario(yaml.safe_dump(data), "<test>", registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, environment, arm, condition, 0)
        runner.run(spec)
        return runner.state.steps(spec.trial_id)
    finally:
        runner.close()
