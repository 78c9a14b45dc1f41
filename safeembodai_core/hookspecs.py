"""Hook specifications: every way a plugin can extend SafeEmbodAI.

A plugin is a module (or object) with functions decorated by :data:`hookimpl` whose names match
the specs below. Two families:

* **registry hooks** (``register_*``) are called once per run to collect named components. The
  plugin calls ``register(name, factory, options=OptionsModel, description="...")``; a scenario
  then selects the component by ``name``. ``factory(options, context)`` builds the component
  from its validated options (a pydantic model with ``extra="forbid"``) and a
  :class:`~safeembodai_core.contracts.components.BuildContext`. Import heavy libraries inside the factory,
  never at module level: registration must stay cheap.
* **lifecycle hooks** are called as trials run, to observe (log, trace, export) without changing
  the loop. An exception raised in one is reported with the plugin's name and ends the trial
  with status ``error``.

See ``docs/plugin_hooks.md`` for one section per hook, and ``docs/plugins.md`` to write a plugin.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Callable, Protocol

import pluggy

if TYPE_CHECKING:  # the contracts' types, without importing them at run time
    import click
    from pydantic import BaseModel

    from .contracts.components import BuildContext
    from .metrics import Metric
    from .models import Observation, StepRecord, TrialResult, TrialSpec

PROJECT = "safeembodai"

hookspec = pluggy.HookspecMarker(PROJECT)
hookimpl = pluggy.HookimplMarker(PROJECT)


class Register(Protocol):
    """The ``register`` callable passed to the component registry hooks
    (:meth:`~safeembodai_core.plugin.registry.ComponentRegistry.registrar`).

    ``options`` defaults to a model that takes no options; ``description`` to ``""``.
    """

    def __call__(self, name: str, factory: Callable[[Any, BuildContext], Any], *,
                 options: type[BaseModel] = ..., description: str = ...) -> None: ...


#: The ``register`` callable passed to :func:`register_metrics`
#: (:meth:`~safeembodai_core.metrics.catalog.CatalogBuilder.registrar`).
RegisterMetric = Callable[["Metric"], None]


# --- Component registries: world and robot ---------------------------------------------------


@hookspec
def register_environments(register: Register) -> None:
    """Register simulated worlds (``Environment`` factories), e.g. the paper's ``OF``/``SO``/``DO``/``MO``.

    :param register: call ``register(name, factory, options=Model, description=...)`` once per
        environment. ``factory(options, context)`` returns an
        :class:`~safeembodai_core.contracts.components.Environment`.
    """


@hookspec
def register_perceptions(register: Register) -> None:
    """Register perception stages that turn raw sensor readings into prompt modalities.

    :param register: call ``register(name, factory, options=Model, description=...)``;
        ``factory`` returns a :class:`~safeembodai_core.contracts.components.Perception` whose
        ``perceive(observation)`` gives camera/LiDAR images and/or text descriptions.
    """


# --- Component registries: the three defences --------------------------------------------------


@hookspec
def register_prompt_builders(register: Register) -> None:
    """Register prompt builders (secure prompting: system prompt Y = {B, p} and user prompt I_i).

    :param register: call ``register(name, factory, options=Model, description=...)``;
        ``factory`` returns a :class:`~safeembodai_core.contracts.components.PromptBuilder`.
    """


@hookspec
def register_state_stores(register: Register) -> None:
    """Register state stores (state management: step records and the reference state R_{i-1}).

    :param register: call ``register(name, factory, options=Model, description=...)``;
        ``factory`` returns a :class:`~safeembodai_core.contracts.components.StateStore`.
    """


@hookspec
def register_validators(register: Register) -> None:
    """Register safety-validation rules applied to every control signal before execution.

    :param register: call ``register(name, factory, options=Model, description=...)``;
        ``factory`` returns a :class:`~safeembodai_core.contracts.components.Validator`.
    """


# --- Component registries: adversaries and brains ---------------------------------------------


@hookspec
def register_attackers(register: Register) -> None:
    """Register attackers that tamper with the instruction, sensor readings or reference state.

    :param register: call ``register(name, factory, options=Model, description=...)``;
        ``factory`` returns a :class:`~safeembodai_core.contracts.components.Attacker`.
    """


@hookspec
def register_llm_backends(register: Register) -> None:
    """Register LLM backends (remote APIs, local servers, simulated pilots).

    :param register: call ``register(name, factory, options=Model, description=...)``;
        ``factory`` returns a :class:`~safeembodai_core.contracts.components.LLMBackend`.
    """


# --- Metrics -----------------------------------------------------------------------------------


@hookspec
def register_metrics(register: RegisterMetric) -> None:
    """Add metrics to the catalog every report reads (``metrics.json``/``.csv``, report.md, figures,
    the terminal summary, the Inspect scorers).

    :param register: call ``register(Metric(name, label, compute, ...))`` once per metric, with a
        :class:`~safeembodai_core.metrics.Metric` whose ``compute(cell)`` returns an
        :class:`~safeembodai_core.metrics.Estimate` from a
        :class:`~safeembodai_core.metrics.CellTrials` (the cell's scored trials). A name the
        catalog already has is refused, naming both owners.
    """


# --- Command line ------------------------------------------------------------------------------


@hookspec
def register_commands(cli: click.Group) -> None:
    """Add commands to the ``safeembodai`` command line.

    :param cli: the root :class:`click.Group`; decorate functions with ``@cli.command()``.
    """


# --- Lifecycle events --------------------------------------------------------------------------


@hookspec
def before_trial(spec: TrialSpec) -> None:
    """Called before a trial's world is reset.

    :param spec: the :class:`~safeembodai_core.models.TrialSpec` (cell, index, seed).
    """


@hookspec
def before_step(spec: TrialSpec, step: int, observation: Observation) -> None:
    """Called at the start of step ``step`` (1-based), after the sensors were read and before any
    attacker or the LLM sees them.

    :param spec: the trial's :class:`~safeembodai_core.models.TrialSpec`.
    :param step: the step index i.
    :param observation: the raw :class:`~safeembodai_core.models.Observation`; do not mutate.
    """


@hookspec
def after_step(spec: TrialSpec, record: StepRecord) -> None:
    """Called after step ``record.step`` was executed and recorded in the state store.

    :param spec: the trial's :class:`~safeembodai_core.models.TrialSpec`.
    :param record: the :class:`~safeembodai_core.models.StepRecord` (R_i, attempts, verdicts).
    """


@hookspec
def on_step_error(spec: TrialSpec, step: int, error: Exception) -> None:
    """Called when a step fails with an exception (backend outage, plugin error, ...), before the
    trial ends with status ``error``.

    :param spec: the trial's :class:`~safeembodai_core.models.TrialSpec`.
    :param step: the step index i that failed.
    :param error: the exception.
    """


@hookspec
def after_trial(spec: TrialSpec, result: TrialResult) -> None:
    """Called when a trial has ended and its result was stored.

    :param spec: the trial's :class:`~safeembodai_core.models.TrialSpec`.
    :param result: the :class:`~safeembodai_core.models.TrialResult`.
    """
