"""``fresh_scan``: the validators judge the LiDAR as it reads when the LLM's answer arrives.

Without it (the paper's V(C)) every rule judges the scan the step's prompt was built from, read
before the LLM started thinking; a mover keeps moving through that think time. With it, the loop
asks the environment for a new reading (:meth:`~safeembodai_core.components.Environment.sense`)
as each answer arrives and the rules judge that one: the step's scan joins
``ValidationContext.history`` and ``answer_s`` says the plan starts at the reading's time.

A spoofed sensor stays spoofed: the step's attackers run again on the new reading, with the same
random draws as on the step's observation (each attacker's generator is seeded from the trial,
its key and the step only), and only what they do to the LiDAR is kept; what they record was
recorded with the step's observation already.
"""

from __future__ import annotations

import copy
from dataclasses import replace
from typing import Any, Callable

from .. import seeds
from ..components import AttackSurface
from ..errors import EnvironmentError_
from ..models import Observation
from ..validation import PastScan, ValidationContext


def fresh_context(context: ValidationContext, observation: Observation, *, parts: Any, seed: int, step: int,
                  instruction: str, reference: Any, limits: Any,
                  on_sensed: Callable[[Observation], None]) -> ValidationContext:
    """``context`` (built on the step's observation) moved to a reading taken now.

    ``instruction`` and ``reference`` are the step's, as the attackers first saw them;
    ``on_sensed`` receives the new reading (its truth may report a collision during the think
    time, once). Raises
    :class:`~safeembodai_core.errors.EnvironmentError_` when the environment cannot sense.
    """
    reading = parts.environment.sense()
    if reading is None:
        raise EnvironmentError_(f"environment {type(parts.environment).__name__} cannot read its LiDAR when an "
                                f"answer arrives (Environment.sense), which the arm's fresh_scan needs")
    if not isinstance(reading, Observation):
        raise EnvironmentError_(f"environment {type(parts.environment).__name__}.sense() returned "
                                f"{type(reading).__name__}, not an Observation")
    on_sensed(reading)
    attacked = AttackSurface(step, instruction, copy.copy(reading), reference,
                             rng=seeds.rng(seed, "attacker", "", step), limits=limits)
    for name, attacker in parts.attackers:
        attacked.rng = seeds.rng(seed, "attacker", name, step)
        attacker.attack(attacked)  # its records belong to the step's observation, already kept
    history = context.history
    if context.scan is not None and observation.pose is not None:
        history = history + (PastScan(context.scan, observation.pose, observation.sim_time_s),)
    return replace(context, scan=attacked.observation.lidar, start_pose=reading.pose,
                   sim_time_s=reading.sim_time_s, history=history, answer_s=reading.sim_time_s)
