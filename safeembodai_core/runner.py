"""Turn a scenario into trials: trial specs with paired seeds, and the components to run them.

:class:`ScenarioRunner` is what ``safeembodai run`` uses for one trial and what every ablation
worker uses for many. Environments are expensive (a physics client each), so one instance per
environment label is kept and reset between trials; everything else is built per trial so no
state leaks from one trial into the next.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any


from . import seeds
from .components import BuildContext, LLMBackend, StateStore
from .errors import SafeEmbodAIError
from .loop import LoopSettings, TrialParts, run_trial
from .loop.trial import error_result
from .models import TrialResult, TrialSpec
from .plugins import Plugins
from .refs import ComponentRef
from .run_files import BAG_STORAGE_FILE, BAGS_DIR, read_run_text
from .scenario import Scenario
from .trial_files import FolderFiles, TrialFiles, TrialOutputs, bag_file, trajectory_file

__all__ = ["ScenarioRunner", "bag_file", "preflight", "trajectory_file", "trial_spec"]

from .logs import get_logger

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
    Returns the backend's :attr:`~safeembodai_core.components.LLMBackend.concurrency` (1 when it
    says nothing sensible).
    """
    try:
        plugins.metrics
        backend = ScenarioRunner(scenario, plugins).build("llm_backend", scenario.backend)
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


def recorded_bag_storage(run_dir: str | Path | None) -> str | None:
    """The bag storage a run folder asks for (``bags/storage``), or None when it records no bags."""
    if run_dir is None:
        return None
    marker = Path(run_dir) / BAGS_DIR / BAG_STORAGE_FILE
    try:
        storage = read_run_text(marker, 1024).strip()
    except FileNotFoundError:
        return None
    except OSError as error:
        raise SafeEmbodAIError(f"{marker} is unreadable: {error}") from None
    if storage not in ("mcap", "sqlite3"):
        raise SafeEmbodAIError(f"{marker} says {storage[:40]!r}: it must say mcap or sqlite3")
    return storage


def trial_spec(scenario: Scenario, environment: str, arm: str, condition: str, index: int) -> TrialSpec:
    return TrialSpec(
        trial_id=f"{environment}/{arm}/{condition}/{index}",
        scenario=scenario.name, environment=environment, arm=arm, condition=condition,
        index=index, seed=trial_seed(scenario, environment, index),
    )


class ScenarioRunner:
    """Builds and runs the trials of one scenario with one set of plugins."""

    def __init__(self, scenario: Scenario, plugins: Plugins, run_dir: str | Path | None = None,
                 state: StateStore | None = None, save_trajectories: bool = False,
                 outputs: TrialOutputs | None = None) -> None:
        """``outputs`` stands in for a run folder (a Ray worker's runner: its files, bag storage and
        cache go back to the coordinator, ``ablation/relay.py``); else ``run_dir`` is read and written."""
        self.scenario = scenario
        self.plugins = plugins
        self.run_dir = str(run_dir) if run_dir is not None else None
        self.files: TrialFiles | None = (outputs.files if outputs is not None
                                         else FolderFiles(run_dir) if run_dir is not None else None)
        self.save_trajectories = save_trajectories and self.files is not None
        # a ROS 2 bag per trial, as it ends
        self.bag_storage = outputs.bag_storage if outputs is not None else recorded_bag_storage(run_dir)
        self._environments: dict[str, Any] = {}
        self._state = state
        self._outputs = outputs
        self._cache: Any = None  # the response cache, opened with the first trial of a cacheable backend
        self._simulated: str | None = None  # the backend's banner for trial pictures, read once

    def build(self, kind: str, ref: ComponentRef, seed: int = 0, only_to_describe: bool = False) -> Any:
        """Component ``ref`` of ``kind`` (``only_to_describe``: :class:`BuildContext`'s flag)."""
        context = BuildContext(component=ref.use, kind=kind, seed=seed, run_dir=self.run_dir, label=ref.key,
                               only_to_describe=only_to_describe)
        return self.plugins.registry.build(kind, ref.use, ref.options, context)

    @property
    def state(self) -> StateStore:
        if self._state is None:
            self._state = self.build("state_store", self.scenario.state)
        return self._state

    def environment(self, label: str) -> Any:
        if label not in self._environments:
            self._environments[label] = self.build("environment", self.scenario.environment(label))
        return self._environments[label]

    def parts(self, spec: TrialSpec, backend: LLMBackend | None = None) -> TrialParts:
        """The components of trial ``spec``; ``backend`` replaces the scenario's (which is then
        never built: an integration that brings its own model needs no key for the scenario's)."""
        arm = self.scenario.arms[spec.arm]
        condition = self.scenario.conditions[spec.condition]
        return TrialParts(
            environment=self.environment(spec.environment),
            perception=self.build("perception", self.scenario.perception, spec.seed),
            prompt_builder=self.build("prompt_builder", self.scenario.prompt_builder, spec.seed),
            state=self.state,
            backend=backend if backend is not None else self._cached(
                self.build("llm_backend", self.scenario.backend, spec.seed), spec),
            validators=[(r.key, self.build("validator", r, spec.seed)) for r in arm.validators],
            attackers=[(r.key, self.build("attacker", r, spec.seed)) for r in condition.attackers],
        )

    def _cached(self, backend: LLMBackend, spec: TrialSpec) -> LLMBackend:
        """``backend`` with its replies kept in the run's response cache (``loop/response_cache.py``),
        when it can say what it sends and the run folder keeps a cache; else ``backend`` itself."""
        if type(backend).cache_request is LLMBackend.cache_request:
            return backend
        from .loop.response_cache import CachedBackend, CacheSettings, ResponseCache

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
        try:
            parts = self.parts(spec)
        except SafeEmbodAIError as error:  # e.g. a factory that failed: this trial errs, the run goes on
            log.warning("trial.unbuildable", trial=spec.trial_id, error=str(error))
            result = error_result(spec, f"components could not be built: {error}")
            self.state.begin_trial(spec)
            self.state.end_trial(result)
            return result
        capture = None
        if self.bag_storage is not None:
            from .loop.capture import TrialCapture

            capture = TrialCapture()
            parts.environment, parts.perception = capture.wrap(parts.environment, parts.perception)
        try:
            result = run_trial(spec, parts, self.settings(spec.arm), self.plugins)
        finally:
            parts.backend.close()
        if self.save_trajectories:
            self._save_trajectory(parts.environment, result)
        if capture is not None and self.files is not None:
            self._save_bag(spec, capture, parts, result)
        return result

    def _save_bag(self, spec: TrialSpec, capture: Any, parts: TrialParts, result: TrialResult) -> None:
        """Write the trial's bag (``bags/<trial>``), replacing one a resumed run left of an earlier try.
        A bag that cannot be written stops the run with an error naming it, as a picture does: the
        trial's result is stored (``safeembodai export`` makes the bag again from the run folder)."""
        messages = self.bag_messages(spec, capture, self.state.steps(spec.trial_id), result, parts.environment.robot)
        assert self.files is not None  # checked by the caller
        self.files.bag(spec.trial_id, messages, self.bag_storage or "mcap")

    def bag_messages(self, spec: TrialSpec, capture: Any, records: list[Any], result: TrialResult | None,
                     robot: Any) -> list[Any]:
        """The bag of one trial (:func:`~safeembodai_core.ros.bag_export.trial_messages`), with the
        scenario's word on the arm's defences and the limits in ``/safeembodai/trial``."""
        from .ros.bag_export import trial_messages

        about = {"scenario": self.scenario.name, "arm": self.scenario.arms[spec.arm].model_dump(mode="json"),
                 "limits": self.scenario.limits.model_dump(mode="json")}
        return trial_messages(spec, records, result, capture, robot, about)

    def trajectory_path(self, trial_id: str) -> Path:
        return trajectory_file(self.run_dir or ".", trial_id)

    def trajectory_picture(self, environment: Any, result: TrialResult) -> bytes | None:
        """The trial's picture as ``environment`` draws it, captioned with the trial's id, arm and
        condition and, for a simulated backend, that it is one (``report/captions.py``); None when
        the environment draws none. Raises what the environment's drawing raises."""
        from .report.captions import caption_lines, captioned
        from .report.run_info import describe_backend

        picture = environment.trajectory_png(result.trajectory, result.outcome)
        if not picture:
            return None
        if self._simulated is None:  # the backend's banner, once per runner ("" for an LLM)
            self._simulated = describe_backend(self.scenario, self.plugins).simulated or ""
        return captioned(picture, caption_lines(result.spec, self._simulated or None))

    def _save_trajectory(self, environment: Any, result: TrialResult) -> bool:
        """Draw and write the trial's picture (:meth:`trajectory_picture`); False when the
        environment draws none.

        A drawing bug only costs the picture (a warning). A picture that cannot be written (a
        full disk, ``trajectories`` not a folder) stops the run with an error naming the file: the
        trial's result is already stored, and a resume draws the missing picture again. The file
        appears whole or not at all (written aside, then renamed).
        """
        try:
            picture = self.trajectory_picture(environment, result)
        except Exception as error:  # a picture is a convenience: never lose a trial over it
            log.warning("trajectory.failed", trial=result.spec.trial_id, error=str(error))
            return False
        if not picture or self.files is None:
            return False
        self.files.picture(result.spec.trial_id, picture)
        return True

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
            drawn += self._save_trajectory(environment, result)
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
