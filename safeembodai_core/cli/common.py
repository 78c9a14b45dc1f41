"""Options and helpers shared by the commands that read a scenario."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import click

if TYPE_CHECKING:
    from ..plugins import Plugins
    from ..scenario import Scenario


def scenario_options(function: Callable[..., Any] | None = None, *, required: bool = True) -> Any:
    """``SCENARIO`` plus ``--backend``, ``--seed`` and repeated ``--set key=value``.

    ``@scenario_options(required=False)`` makes ``SCENARIO`` optional (``ablate --resume RUN``
    reads it from the run folder); the command then checks what it was given.
    """
    def decorate(function: Callable[..., Any]) -> Callable[..., Any]:
        function = click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                                help="Override any scenario value (dotted key), validated like the file. "
                                     "Repeatable.")(function)
        function = click.option("--seed", type=int, default=None,
                                help="Base seed (overrides the scenario's).")(function)
        function = click.option("--backend", default=None, metavar="NAME",
                                help="LLM backend by name (overrides the scenario's backend and its "
                                     "options).")(function)
        return click.argument("scenario_path", metavar="SCENARIO" if required else "[SCENARIO]", required=required,
                              type=click.Path(dir_okay=False))(function)

    return decorate if function is None else decorate(function)


def load(scenario_path: str, backend: str | None, seed: int | None,
         overrides: tuple[str, ...]) -> tuple["Scenario", "Plugins"]:
    """Load plugins, then the scenario with CLI overrides applied, checked against the registry."""
    from ..plugins import load_plugins
    from ..scenario import load_scenario

    plugins = load_plugins()
    extra = []
    if backend is not None:
        extra.append(f"backend={backend}")
    if seed is not None:
        extra.append(f"seed={seed}")
    scenario = load_scenario(scenario_path, [*extra, *overrides], plugins.registry)
    return scenario, plugins


def load_recorded(run_dir: str) -> tuple["Scenario", "Plugins"]:
    """Load plugins as :func:`load` does, then the scenario a run folder recorded in ``scenario.json``,
    checked against the registry like a scenario file (a plugin it needs may have gone since)."""
    from ..ablation.run_folder import SCENARIO_FILE, RunFolder
    from ..plugins import load_plugins
    from ..scenario.loader import check_components

    plugins = load_plugins()
    scenario = RunFolder(run_dir).scenario()
    recorded = str(Path(run_dir) / SCENARIO_FILE)
    check_components(scenario, plugins.registry, lambda loc: recorded)
    return scenario, plugins
