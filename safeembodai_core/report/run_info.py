"""What a report says before any number: which backend and model, which seed, which scenario
(its fingerprint), how many trials per cell -- and, for a simulated pilot, that it is one and which
of its options are the inputs behind the numbers that look like findings.

The backend describes itself (:meth:`~safeembodai_core.contracts.components.BackendOptions.describe`, on its
options model: nothing is built, no key is needed): the report lists no plugin's names. A backend
whose options model does not describe it is named by its ``model`` option, and taken for an LLM.
A backend whose replies name the model that answered (litellm's) is named by those names when the
run's results are at hand.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..contracts.descriptions import EnvironmentDescription
from ..scenario import Scenario
from ..scenario.describe import describe_backend, describe_environments, told_arms


@dataclass(frozen=True)
class RunInfo:
    backend: str
    model: str
    seed: int
    fingerprint: str
    trials_per_cell: int
    simulated: str | None = None  # the banner, for a simulated backend
    model_id: str | None = None  # the backend's model option as configured (a litellm id), when it has one
    model_source: str | None = None  # how ``model`` was read off the configuration (litellm's backends)
    inputs: list[tuple[str, Any, str]] = field(default_factory=list)  # (option, value, what it sets)
    weaknesses: list[tuple[str, Any]] = field(default_factory=list)
    clocks: dict[str, EnvironmentDescription] = field(default_factory=dict)  # environment label -> its clock
    why: str | None = None  # with a banner: what every number follows from
    pilot_words: str | None = None  # with a banner: a legend's few words
    told: dict[str, list[str]] = field(default_factory=dict)  # arm -> world-private options it sets (`told`)

    def as_dict(self) -> dict[str, Any]:
        return {"backend": self.backend, "model": self.model, "model_id": self.model_id,
                "model_source": self.model_source, "seed": self.seed, "fingerprint": self.fingerprint,
                "trials_per_cell": self.trials_per_cell, "simulated": self.simulated,
                "pilot_inputs": {name: value for name, value, _ in self.inputs},
                "pilot_weaknesses": dict(self.weaknesses)}

    @property
    def pilot(self) -> str:
        """Who answered, in a few words: ``local/SmolLM2``, or a simulated pilot named as not an LLM."""
        if self.simulated:
            return self.pilot_words or f"{self.backend} (not known to be an LLM)"
        return f"{self.backend}/{self.model}"

    def bars(self) -> str:
        """What a figure's bars show: who answered and the trials per cell."""
        return f"bars: {self.pilot}, N = {self.trials_per_cell} trials per cell"


def _recorded_fingerprint(folder: Path | None) -> str | None:
    if folder is None:
        return None
    from ..runs.folder import RunFolder
    from ..errors import SafeEmbodAIError

    try:
        return RunFolder(folder).recorded_scenario()["fingerprint"]
    except SafeEmbodAIError:  # no run folder's scenario: the report says so
        return None


def _answered_by(results: Any) -> list[str]:
    """The model names the trials' replies gave, most trials first."""
    counts: dict[str, int] = {}
    for result in results or ():
        for name in getattr(result, "models", ()):
            counts[name] = counts.get(name, 0) + 1
    return sorted(counts, key=lambda name: -counts[name])


def run_info(scenario: Scenario, folder: str | Path | None = None, plugins: Any = None,
             results: Any = None) -> RunInfo:
    """The report's header facts; the fingerprint is the run folder's, else the scenario's own.
    With ``results``, a backend whose replies name the model is named by them."""
    from ..runs.folder import fingerprint

    described = describe_backend(scenario, plugins)
    recorded = _recorded_fingerprint(Path(folder) if folder is not None else None)
    model, source = described.model or "(the backend's own)", described.model_source
    named = _answered_by(results) if described.names_model_in_replies else []
    if named:
        model = ", ".join(named[:3])
        source = f"as the server named it in its replies (configured: `{described.model_id or 'none'}`)"
    return RunInfo(backend=scenario.backend.use, model=model, seed=scenario.seed,
                   fingerprint=recorded or fingerprint(scenario), trials_per_cell=scenario.trials,
                   simulated=described.simulated, model_id=described.model_id, model_source=source,
                   inputs=list(described.inputs), weaknesses=list(described.weaknesses),
                   clocks=describe_environments(scenario, plugins), why=described.why, pilot_words=described.pilot,
                   told=told_arms(scenario, plugins))
