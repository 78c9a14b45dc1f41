"""Inspect AI's entry point into SafeEmbodAI (``[project.entry-points.inspect_ai]``; the ``inspect`` extra).

Inspect names a package's tasks ``<top-level module>/<task>`` and finds them through the entry
point named after that prefix; this module is named after the distribution so that the tasks are
``safeembodai/<scenario>`` in a wheel and in an editable install alike. It only registers names:
the work is in :mod:`safeembodai_core.integrations.inspect` (``docs/inspect.md``).

* ``safeembodai/<name>`` for every shipped scenario (``mo``, ``paper``, ...), ``safeembodai/scenario``
  for a file: ``inspect eval safeembodai/scenario -T scenario=my.yaml``. Task arguments:
  ``scenario``, ``trials``, ``seed``, ``max_steps``, ``set`` (``--set``-style overrides) and
  ``image_detail``.
* the model provider ``safeembodai``: ``--model safeembodai/mock`` is the simulated pilot
  (``-M key=value`` sets its options).
"""

from __future__ import annotations

from typing import Any, Callable

from inspect_ai import Task, task
from inspect_ai.model import modelapi


def _scenario_task(default: str | None) -> Callable[..., Task]:
    def scenario_task(scenario: str | None = default, trials: int | None = None, seed: int | None = None,
                      max_steps: int | None = None, set: Any = None, image_detail: str = "low") -> Task:
        from safeembodai_core.integrations.inspect import scenario_task as build

        return build(scenario, trials=trials, seed=seed, max_steps=max_steps, set=set, image_detail=image_detail)

    scenario_task.__doc__ = (f"The ablation of scenarios/{default}.yaml (or -T scenario=PATH) with Inspect's model."
                             if default else "The ablation of the scenario file -T scenario=PATH with Inspect's model.")
    return scenario_task


def _prefix() -> str:
    """What to put before a task's name so that Inspect registers it as ``safeembodai/<name>``.

    Inspect prefixes the module's name itself when it finds the module installed; it does not
    when the ``safeembodai`` distribution it finds has no install record (run from the source
    folder, Python sees ``safeembodai.egg-info`` there first): then the prefix is written here.
    """
    try:
        from inspect_ai._util.package import get_installed_package_name
    except ImportError:  # moved in a later Inspect: assume the documented behaviour
        return ""
    return "" if get_installed_package_name(_prefix) == __name__ else f"{__name__}/"


def _register() -> None:
    from safeembodai_core.integrations.inspect.task import SHIPPED

    prefix = _prefix()
    for name in (*SHIPPED, "scenario"):
        globals()[name] = task(name=prefix + name)(_scenario_task(None if name == "scenario" else name))


_register()


@modelapi(name="safeembodai")
def _provider() -> type:
    from safeembodai_core.integrations.inspect.provider import SafeEmbodAIModelAPI

    return SafeEmbodAIModelAPI
