"""Turn a scenario into trials: trial specs with paired seeds, and the components to run them.

:class:`ScenarioRunner` is what ``safeembodai run`` uses for one trial and what every ablation
worker uses for many. Environments are expensive (a physics client each), so one instance per
environment label is kept and reset between trials; everything else is built per trial so no
state leaks from one trial into the next.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


from .. import seeds
from ..plugin.building import ComponentBuilder
from ..contracts.components import LLMBackend, StateStore
from ..errors import SafeEmbodAIError
from ..loop import LoopSettings, TrialParts, run_trial
from ..loop.trial import error_result
from ..models import TrialResult, TrialSpec
from ..plugin.manager import Plugins
from ..scenario import Scenario
from .artefacts import TrialArtefacts
from .trial_files import ArtefactSettings, FolderFiles, TrialFiles, TrialOutputs, bag_file, trajectory_file

__all__ = ["ScenarioRunner", "bag_file", "preflight", "trajectory_file", "trial_spec"]

from ..logs import get_logger

log = get_logger(__name__)


def trial_seed(scenario: Scenario, environment: str, index: int) -> int:
    """The seed of trial ``index`` in the environment labelled ``environment``.

    From the base seed, the environment's label and the index only: every arm and condition of
    one environment meets the same world at index k (paired comparisons), while each environment
    draws its own worlds (its own robot and can placements, its own pilot dice).
    """
    return seeds.derive_seed(scenario.seed, "trial", environment, index)


def preflight(scenario: Scenario, plugins: Plugins) -> int:
    """Fail before the first trial, with one line, when the scenario's backend cannot work.

    Builds the backend once (a missing API key fails its factory) and calls its optional
    ``preflight()`` (the built-in litellm backends check that the server accepts a connection),
    and collects the metric catalog (a plugin's clashing metric fails here, not at the report).
    Nothing is written anywhere: ``run`` and ``ablate`` call this before making any folder.
    Returns the backend's :attr:`~safeembodai_core.contracts.components.LLMBackend.concurrency` (1 when it
    says nothing sensible).
    """
    try:
        plugins.metrics
        backend = ComponentBuilder(scenario, plugins).backend()
        try:
            backend.preflight()
            suggested = backend.concurrency
        finally:
            backend.close()
    except SafeEmbodAIError as error:
        raise PreflightError(f"{error} (checked before the first trial: nothing was run)") from None
    return suggested if type(suggested) is int and 1 <= suggested <= 256 else 1


class PreflightError(SafeEmbodAIError):
    """The scenario's backend cannot work (no key, no server): raised before any trial runs."""


def trial_spec(scenario: Scenario, environment: str, arm: str, condition: str, index: int) -> TrialSpec:
    return TrialSpec(
        trial_id=f"{environment}/{arm}/{condition}/{index}",
        scenario=scenario.name, environment=environment, arm=arm, condition=condition,
        index=index, seed=trial_seed(scenario, environment, index),
    )


class ScenarioRunner:
    """Runs the trials of one scenario with one set of plugins: each trial's components come from a
    :class:`~.building.ComponentBuilder`, what it leaves beside its records is written by a
    :class:`~.trial_artefacts.TrialArtefacts`."""

    def __init__(self, scenario: Scenario, plugins: Plugins, run_dir: str | Path | None = None,
                 state: StateStore | None = None, save_trajectories: bool = False,
                 outputs: TrialOutputs | None = None) -> None:
        """``outputs`` stands in for a run folder (a Ray worker's runner: its files, bags, recordings
        and cache go back to the coordinator, ``ablation/relay.py``); else ``run_dir`` is read and written."""
        self.scenario = scenario
        self.plugins = plugins
        self.run_dir = str(run_dir) if run_dir is not None else None
        self.builder = ComponentBuilder(scenario, plugins, run_dir)
        files: TrialFiles | None = (outputs.files if outputs is not None
                                    else FolderFiles(run_dir) if run_dir is not None else None)
        settings = outputs.settings if outputs is not None else ArtefactSettings.recorded(run_dir)
        self.artefacts = TrialArtefacts(scenario, plugins, files, pictures=save_trajectories, settings=settings)
        self._environments: dict[str, Any] = {}
        self._state = state
        self._outputs = outputs
        self._cache: Any = None  # the response cache, opened with the first trial of a cacheable backend

    @property
    def state(self) -> StateStore:
        if self._state is None:
            self._state = self.builder.state_store()
        return self._state

    def environment(self, label: str) -> Any:
        """The environment labelled ``label``, built once and kept for every trial of this runner."""
        if label not in self._environments:
            self._environments[label] = self.builder.environment(label)
        return self._environments[label]

    def parts(self, spec: TrialSpec, backend: LLMBackend | None = None) -> TrialParts:
        """The components of trial ``spec``; ``backend`` replaces the scenario's (which is then
        never built: an integration that brings its own model needs no key for the scenario's)."""
        arm = self.scenario.arms[spec.arm]
        condition = self.scenario.conditions[spec.condition]
        build = self.builder.build
        return TrialParts(
            environment=self.environment(spec.environment),
            perception=build("perception", self.scenario.perception, spec.seed),
            prompt_builder=build("prompt_builder", self.scenario.prompt_builder, spec.seed),
            state=self.state,
            backend=backend if backend is not None else self._cached(self.builder.backend(spec.seed), spec),
            validators=[(r.key, build("validator", r, spec.seed)) for r in arm.validators],
            attackers=[(r.key, build("attacker", r, spec.seed)) for r in condition.attackers],
        )

    def _cached(self, backend: LLMBackend, spec: TrialSpec) -> LLMBackend:
        """``backend`` with its replies kept in the run's response cache (``loop/response_cache.py``),
        when it can say what it sends and the run folder keeps a cache; else ``backend`` itself."""
        if type(backend).cache_request is LLMBackend.cache_request:
            return backend
        from ..loop.response_cache import CachedBackend, CacheSettings, ResponseCache

        if self._outputs is not None:
            cache = self._outputs.cache
            return backend if cache is None else CachedBackend(backend, cache, spec.trial_id)
        if self.run_dir is None:
            return backend
        if self._cache is None:
            settings = CacheSettings.recorded(self.run_dir)
            if not settings.enabled:
                return backend
            self._cache = ResponseCache(settings.path(self.run_dir), read=settings.read)
        return CachedBackend(backend, self._cache, spec.trial_id)

    def settings(self, arm: str) -> LoopSettings:
        s = self.scenario
        return LoopSettings(max_steps=s.max_steps, instruction=s.instruction, task=s.task,
                            defences=s.arms[arm], limits=s.limits, budget=s.budget)

    def run(self, spec: TrialSpec) -> TrialResult:
        """Run trial ``spec`` (its records and result go to the state store), then write what it
        leaves (:meth:`TrialArtefacts.after_trial`); a trial whose components cannot be built is
        stored as an ``error`` result and the run goes on."""
        try:
            parts = self.parts(spec)
        except SafeEmbodAIError as error:  # e.g. a factory that failed: this trial errs, the run goes on
            log.warning("trial.unbuildable", trial=spec.trial_id, error=str(error))
            result = error_result(spec, f"components could not be built: {error}")
            self.state.begin_trial(spec)
            self.state.end_trial(result)
            return result
        capture = None
        if self.artefacts.capture:
            from ..loop.capture import TrialCapture

            capture = TrialCapture()
            parts.environment, parts.perception = capture.wrap(parts.environment, parts.perception)
        try:
            result = run_trial(spec, parts, self.settings(spec.arm), self.plugins)
        finally:
            parts.backend.close()
        self.artefacts.after_trial(spec, parts.environment, capture, result,
                                   lambda: self.state.steps(spec.trial_id))
        return result

    def trajectory_path(self, trial_id: str) -> Path:
        return trajectory_file(self.run_dir or ".", trial_id)

    def draw_missing_trajectories(self, results: list[TrialResult]) -> int:
        """Draw the pictures of ``results`` that have none (a run killed between storing a result
        and writing its picture); return how many were drawn.

        Each is drawn from the recorded path on the world reset to the trial's seed: the room,
        the path and static obstacles are exact; marks a world only keeps while a trial runs
        (where it collided, moving obstacles' tracks) may be missing.
        """
        drawn = 0
        for result in results:
            if not result.trajectory or self.trajectory_path(result.spec.trial_id).exists():
                continue
            try:
                environment = self.environment(result.spec.environment)
                environment.reset(result.spec.seed)
            except Exception as error:  # SafeEmbodAIError included: the picture stays missing, the report says so
                log.warning("trajectory.failed", trial=result.spec.trial_id, error=str(error))
                continue
            drawn += self.artefacts.save_picture(environment, result)
        return drawn

    def specs(self) -> list[TrialSpec]:
        """Every trial of the scenario, cell by cell."""
        return [trial_spec(self.scenario, e, a, c, i) for (e, a, c) in self.scenario.cells()
                for i in range(self.scenario.trials)]

    def in_trial_order(self, results: list[TrialResult]) -> list[TrialResult]:
        """``results`` sorted as :meth:`specs` lists the trials (cell by cell, index by index)."""
        order = {spec.trial_id: i for i, spec in enumerate(self.specs())}
        return sorted(results, key=lambda r: order.get(r.spec.trial_id, len(order)))

    def close(self) -> None:
        for env in self._environments.values():
            env.close()
        self._environments.clear()
        self._cache = None
        if self._state is not None:
            self._state.close()
