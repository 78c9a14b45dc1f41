"""A scenario as an Inspect task: one sample per trial, paired seeds as in ``safeembodai ablate``.

The samples are :meth:`ScenarioRunner.specs() <safeembodai_core.runs.runner.ScenarioRunner.specs>`,
cell by cell and index by index: the id is the trial id (``MO/baseline/attack/3``), the seed is
:func:`~safeembodai_core.runs.runner.trial_seed`'s, so every arm and condition of an environment meets
the same world at index k, and the same trial under ``ablate`` and under Inspect is the same
world. The scenario's own ``backend`` is not used: the model is Inspect's (``--model``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from inspect_ai import Task
from inspect_ai.dataset import MemoryDataset, Sample

from ...errors import SafeEmbodAIError
from ...scenario.reading import checked_scenario
from ...plugin.manager import Plugins
from ...report.cells import attacked
from ...runs.runner import ScenarioRunner
from .providers import check_active_model
from .scorers import CELL, catalog_scorers
from .solver import RunnerPool, trial_solver

#: The source tree's ``scenarios/`` folder (absent from a wheel: there, pass -T scenario=PATH).
SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"

#: The scenarios shipped in ``scenarios/``, each a task ``safeembodai/<name>`` (and any other file
#: there when the tasks are registered).
SHIPPED = tuple(dict.fromkeys(("quickstart", "mo", "so", "of", "do", "paper", "attacks", "components",
                               "eyesim_release", *sorted(p.stem for p in SCENARIOS.glob("*.yaml")))))


def scenario_path(scenario: str | None) -> Path:
    """A scenario file: ``scenario`` itself when it is a file, else ``scenarios/<scenario>.yaml`` of
    the source tree (or of the current folder)."""
    if not scenario:
        raise SafeEmbodAIError("no scenario: pass one with -T scenario=PATH (a file, or a shipped name such as mo)")
    given = Path(scenario).expanduser()
    if given.is_file():
        return given
    for folder in (SCENARIOS, Path.cwd() / "scenarios"):
        candidate = folder / f"{scenario}.yaml"
        if candidate.is_file():
            return candidate
    raise SafeEmbodAIError(f"no scenario file {scenario!r} and no scenarios/{scenario}.yaml in the source tree or "
                           f"the current folder: pass a path with -T scenario=PATH")


def cell_label(spec: Any) -> str:
    """A cell's name as Inspect shows it: ``MO baseline no_attack`` -- words, so that Inspect's terminal
    table wraps a long name at its spaces instead of cutting it ("MO/baselin..." for every cell)."""
    return f"{spec.environment} {spec.arm} {spec.condition}"


def _overrides(trials: int | None, seed: int | None, max_steps: int | None,
               set: str | Iterable[str] | None) -> list[str]:
    extra = [f"{key}={value}" for key, value in (("trials", trials), ("seed", seed), ("max_steps", max_steps))
             if value is not None]
    if isinstance(set, str):
        set = [set]
    return [*extra, *(set or [])]


def scenario_task(scenario: str | None, trials: int | None = None, seed: int | None = None,
                  max_steps: int | None = None, set: str | Iterable[str] | None = None, image_detail: str = "low",
                  plugins: Plugins | None = None) -> Task:
    """The Inspect task of ``scenario`` (a shipped name or a path), with ``--set``-style overrides.

    ``plugins`` (library use, tests) replaces the installed plugins
    (:func:`~safeembodai_core.plugin.manager.load_plugins`).
    A model of a provider that cannot show the whole reply is refused here when ``inspect eval`` has
    set it already, else by the solver (:mod:`.providers`).
    """
    check_active_model()
    loaded, plugins = checked_scenario(scenario_path(scenario), plugins, _overrides(trials, seed, max_steps, set))
    runner = ScenarioRunner(loaded, plugins)
    specs = {spec.trial_id: spec for spec in runner.specs()}
    samples = [
        Sample(id=spec.trial_id, input=loaded.instruction,
               metadata={CELL: cell_label(spec), "environment": spec.environment,
                         "arm": spec.arm, "condition": spec.condition, "index": spec.index, "seed": spec.seed})
        for spec in specs.values()
    ]
    attacked_conditions = [name for name in loaded.conditions if attacked(loaded, name)]
    settings: dict[str, Any] = loaded.metrics.model_dump(mode="json")
    return Task(
        name=loaded.name,
        dataset=MemoryDataset(samples, name=loaded.name),
        solver=trial_solver(RunnerPool(loaded, plugins), specs, image_detail),
        scorer=catalog_scorers(plugins.metrics, settings, loaded.max_steps, attacked_conditions),
        metadata={"scenario": loaded.name, "seed": loaded.seed, "trials": loaded.trials,
                  "max_steps": loaded.max_steps, "cells": [list(cell) for cell in loaded.cells()]},
    )
