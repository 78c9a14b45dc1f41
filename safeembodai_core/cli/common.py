"""Options and helpers shared by the commands that read a scenario."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable

import click

if TYPE_CHECKING:
    from ..plugin.manager import Plugins
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
    """The installed plugins and the scenario file with the CLI's overrides applied, checked as every
    way into a run checks it (:func:`~safeembodai_core.scenario.reading.checked_scenario`)."""
    from ..scenario.reading import checked_scenario

    extra = []
    if backend is not None:
        extra.append(f"backend={backend}")
    if seed is not None:
        extra.append(f"seed={seed}")
    return checked_scenario(scenario_path, overrides=[*extra, *overrides])


def load_recorded(run_dir: str) -> tuple["Scenario", "Plugins"]:
    """The installed plugins and the scenario a run folder recorded in ``scenario.json``, checked
    like a scenario file (:func:`~safeembodai_core.scenario.reading.recorded_scenario`)."""
    from ..scenario.reading import recorded_scenario

    return recorded_scenario(run_dir)
