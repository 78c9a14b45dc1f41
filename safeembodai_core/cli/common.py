"""Options and helpers shared by the commands that read a scenario."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import click

if TYPE_CHECKING:
    from ..plugins import Plugins
    from ..scenario import Scenario


def scenario_options(function: Callable[..., Any]) -> Callable[..., Any]:
    """``SCENARIO`` plus ``--backend``, ``--seed`` and repeated ``--set key=value``."""
    function = click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                            help="Override any scenario value (dotted key), validated like the file. Repeatable.")(function)
    function = click.option("--seed", type=int, default=None, help="Base seed (overrides the scenario's).")(function)
    function = click.option("--backend", default=None, metavar="NAME",
                            help="LLM backend by name (overrides the scenario's backend and its options).")(function)
    function = click.argument("scenario_path", metavar="SCENARIO", type=click.Path(dir_okay=False))(function)
    return function


def load(scenario_path: str, backend: str | None, seed: int | None, overrides: tuple[str, ...]) -> tuple["Scenario", "Plugins"]:
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
