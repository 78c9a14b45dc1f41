"""How a scenario's components describe themselves, for every surface that says what ran: the backend (an
LLM, or a simulated pilot said to be one), each environment's clock, the arms told what only the simulator
knows. A component that cannot describe itself (its plugin gone, its options stale, its ``describe()``
failing) is said to be unknown, never taken for an LLM (fail closed).
"""

from __future__ import annotations

from typing import Any

from ..contracts.descriptions import BackendDescription, BackendOptions, EnvironmentDescription, EnvironmentOptions
from ..plugin.refs import ComponentRef
from .model import Scenario


def describe_backend(scenario: Scenario, plugins: Any = None) -> BackendDescription:
    """The scenario's backend as it describes itself (:func:`describe_ref`)."""
    return describe_ref(scenario.backend, plugins)


def describe_ref(backend: ComponentRef, plugins: Any = None) -> BackendDescription:
    """A backend (``use`` and options) as it describes itself; one whose options model says nothing is
    named by its ``model`` option (taken for an LLM). One that cannot be described -- its plugin is gone,
    its options no longer validate -- is said to be unknown, never taken for an LLM (fail closed)."""
    from ..errors import SafeEmbodAIError

    try:
        options = _validated("llm_backend", backend, plugins)
    except SafeEmbodAIError as error:
        return _undescribed(backend, str(error))
    if isinstance(options, BackendOptions):
        try:
            described = options.describe()
        except Exception as error:  # a plugin's describe() that fails: not described, said so
            return _undescribed(backend, f"its describe() failed: {type(error).__name__}: {error}")
        if not isinstance(described, BackendDescription):
            return _undescribed(backend, f"its describe() returned {type(described).__name__}")
        return described
    model = options.model_dump().get("model")  # a plain options model: named by its model option
    return BackendDescription(model=str(model) if model else None)


def describe_environments(scenario: Scenario, plugins: Any = None) -> dict[str, EnvironmentDescription]:
    """Each environment's clock as it describes itself (:class:`EnvironmentOptions`); an environment that
    cannot say (no such options model, its plugin gone) has none listed."""
    clocks = {}
    for ref in scenario.environments:
        try:
            options = _validated("environment", ref, plugins)
            described = options.describe() if isinstance(options, EnvironmentOptions) else None
        except Exception:  # its plugin gone, its options stale, its describe() failing: no clock listed
            continue
        if isinstance(described, EnvironmentDescription):
            clocks[ref.key] = described
    return clocks


def told_arms(scenario: Scenario, plugins: Any = None) -> dict[str, list[str]]:
    """Each arm told what only the simulator knows (:func:`~safeembodai_core.trust.world_private.arms_told`)."""
    from ..trust.world_private import arms_told

    if plugins is None:
        from ..plugin.manager import load_plugins

        plugins = load_plugins()
    return arms_told(scenario, plugins.registry)


def _validated(kind: str, ref: ComponentRef, plugins: Any) -> Any:
    """``ref``'s options as its registered options model reads them (the installed plugins when
    ``plugins`` is None); raises :class:`SafeEmbodAIError` when its plugin is gone or they do not validate."""
    if plugins is None:
        from ..plugin.manager import load_plugins

        plugins = load_plugins()
    return plugins.registry.validate_options(kind, ref.use, ref.options)


def _undescribed(backend: ComponentRef, reason: str) -> BackendDescription:
    """A backend that cannot describe itself: named by its ``model`` option and never taken for an LLM.
    Its name and the reason come from a run folder or a plugin: one line of terminal-safe text."""
    from ..trust.text import one_line, terminal_text

    model = backend.options.get("model")
    name, why = (one_line(terminal_text(str(text)))[:200] for text in (backend.use, reason.splitlines()[0]
                                                                        if reason else ""))
    return BackendDescription(
        model=one_line(terminal_text(str(model)))[:200] if model else None,
        simulated=f"backend '{name}' could not describe itself ({why}): not known to be an LLM",
        why="Whether an LLM answered is not known: read every number below with that in mind.",
        pilot=f"{name} (not known to be an LLM)")
