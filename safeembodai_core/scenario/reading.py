"""Reading a scenario, the one way in: a YAML file (with ``--set`` overrides) or a ``Scenario`` object,
or what a run folder recorded, checked against the loaded plugins.

Every way in -- ``safeembodai ablate`` and ``run``, a library user's ``Ablation``, the Inspect task,
the Gymnasium env, the agent ablation -- reads its scenario here, before anything runs: every component
it names exists and its options validate, and the metric catalog has no clash. Errors name the file and
the field at fault.
"""

from __future__ import annotations

from pathlib import Path
from typing import Iterable

from ..errors import ScenarioError
from ..plugin.manager import Plugins, load_plugins
from .loader import check_components, load_scenario
from .model import Scenario


def checked_scenario(source: Scenario | str | Path, plugins: Plugins | None = None,
                     overrides: Iterable[str] = ()) -> tuple[Scenario, Plugins]:
    """The scenario ``source`` (a :class:`Scenario`, or a YAML file read with ``--set``-style
    ``overrides``) checked against ``plugins`` (default: the installed ones): every component it
    names exists and its options validate, and the metric catalog has no clash. Raises
    :class:`~safeembodai_core.errors.ScenarioError` naming the file and field at fault."""
    plugins = plugins or load_plugins()
    if isinstance(source, Scenario):
        if overrides:
            raise ScenarioError("overrides apply to a scenario file, not to a Scenario object: "
                                "use Scenario.model_copy(update=...) instead")
        check_components(source, plugins.registry)
        scenario = source
    else:
        scenario = load_scenario(source, list(overrides), plugins.registry)
    plugins.metrics  # a plugin's clashing metric fails here, not at the report
    return scenario, plugins


def recorded_scenario(run_dir: str | Path, plugins: Plugins | None = None) -> tuple[Scenario, Plugins]:
    """The scenario a run folder recorded (``scenario.json``), checked as :func:`checked_scenario`
    checks a file (a plugin it needs may have gone since); errors name ``scenario.json``."""
    from ..runs.folder import SCENARIO_FILE, RunFolder

    plugins = plugins or load_plugins()
    scenario = RunFolder(run_dir).scenario()
    recorded = str(Path(run_dir) / SCENARIO_FILE)
    check_components(scenario, plugins.registry, lambda loc: recorded)
    plugins.metrics
    return scenario, plugins
