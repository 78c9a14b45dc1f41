"""``fresh_scan``: the validators judge the LiDAR as it reads when the LLM's answer arrives.

Without it (the paper's V(C)) every rule judges the scan the step's prompt was built from, read
before the LLM started thinking; a mover keeps moving through that think time. With it, the loop
asks the environment for a new reading (:meth:`~safeembodai_core.contracts.components.Environment.sense`)
as each answer arrives and the rules judge that one: the step's scan joins
``ValidationContext.history`` and ``answer_s`` says the plan starts at the reading's time.

A spoofed sensor stays spoofed: the step's attackers run again on each new reading (the step's
observation with the new LiDAR, pose, truth and time), with the same random draws as on the step's
observation (each attacker's generator is seeded from the trial, its key and the step only), and
only what they do to the LiDAR is kept; what they record was recorded with the step's observation.
A reading older than the step's, or without the LiDAR or pose the step had, is an environment error.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any, Callable

from ..contracts.attack_schedule import attack_stream, run_attackers
from ..contracts.components import AttackSurface, Environment
from ..errors import EnvironmentError_
from ..models import Observation
from ..validation.context import PastScan, ValidationContext


def _cannot_sense(environment: Any, why: str) -> EnvironmentError_:
    return EnvironmentError_(f"environment {type(environment).__name__} cannot read its LiDAR when an answer "
                             f"arrives ({why}), which the arm's fresh_scan needs")


def require_sense(environment: Any) -> None:
    """Refuse, before a trial starts, an environment that does not implement ``sense`` (its class
    keeps :class:`~safeembodai_core.contracts.components.Environment`'s, which reads nothing)."""
    if getattr(type(environment), "sense", None) is Environment.sense:
        raise _cannot_sense(environment, "it does not implement Environment.sense")


def sense_now(environment: Any, observation: Observation, needs_lidar: bool,
              on_sensed: Callable[[Observation], None] = lambda reading: None) -> Observation:
    """The environment's reading as an answer arrives (:meth:`Environment.sense`), checked: an
    Observation, not older than the step's ``observation``, with a LiDAR (when ``needs_lidar``) and a
    pose where the step had them. ``on_sensed`` receives it first (its truth may report a collision
    during the think time, once: on record before anything about the reading is refused). Raises
    :class:`~safeembodai_core.errors.EnvironmentError_` otherwise."""
    reading = environment.sense()
    if reading is None:
        raise _cannot_sense(environment, "its sense() returned None")
    name = type(environment).__name__
    if not isinstance(reading, Observation):
        raise EnvironmentError_(f"environment {name}.sense() returned {type(reading).__name__}, not an Observation")
    on_sensed(reading)
    time_s = reading.sim_time_s
    if isinstance(time_s, bool) or not isinstance(time_s, (int, float)) or not math.isfinite(time_s) \
            or time_s < observation.sim_time_s:
        raise EnvironmentError_(f"environment {name}.sense() read at sim_time_s={time_s!r}, not a time at or "
                                f"after the step's observation ({observation.sim_time_s:g} s): a reading as the "
                                f"answer arrives cannot be older than the step")
    if (needs_lidar and reading.lidar is None) or (observation.pose is not None and reading.pose is None):
        raise EnvironmentError_(f"environment {name}.sense() gave no {'LiDAR' if reading.lidar is None else 'pose'}"
                                f" where the step's observation had one")
    return reading


def attacked_reading(reading: Observation, observation: Observation, attackers: Any, *, seed: int, step: int,
                     instruction: str, reference: Any, limits: Any) -> Observation:
    """The step's readings with the new LiDAR, pose, truth and time, after the step's attackers ran on
    them again: an attacker finds what it found on the step (the camera frame too) and changes the LiDAR
    as it did there. Its records belong to the step's observation, already kept."""
    attacked = AttackSurface(step, instruction, replace(observation, lidar=reading.lidar, pose=reading.pose,
                                                        truth=reading.truth, sim_time_s=reading.sim_time_s),
                             reference, rng=attack_stream(seed, "", step), limits=limits)
    run_attackers(attacked, attackers, seed, step)
    return attacked.observation


def fresh_context(context: ValidationContext, observation: Observation, *, parts: Any, seed: int, step: int,
                  instruction: str, reference: Any, limits: Any,
                  on_sensed: Callable[[Observation], None]) -> ValidationContext:
    """``context`` (built on the step's observation) moved to a reading taken now (:func:`sense_now`,
    :func:`attacked_reading`): the step's scan joins the history, the plan starts at the reading's time.

    ``instruction`` and ``reference`` are the step's, as the attackers first saw them;
    ``on_sensed`` receives the new reading. Raises
    :class:`~safeembodai_core.errors.EnvironmentError_` when the environment cannot sense.
    """
    reading = sense_now(parts.environment, observation, context.scan is not None, on_sensed)
    attacked = attacked_reading(reading, observation, parts.attackers, seed=seed, step=step,
                                instruction=instruction, reference=reference, limits=limits)
    history = context.history
    if context.scan is not None and observation.pose is not None and observation.sim_time_s < reading.sim_time_s:
        history = history + (PastScan(context.scan, observation.pose, observation.sim_time_s),)
    return replace(context, scan=attacked.lidar, start_pose=reading.pose,
                   sim_time_s=reading.sim_time_s, history=history, answer_s=reading.sim_time_s)
