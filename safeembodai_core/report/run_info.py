"""What a report says before any number: which backend and model, which seed, which scenario
(its fingerprint), how many trials per cell -- and, for a simulated pilot, that it is one and which
of its options are the inputs behind the numbers that look like findings.

The built-in simulated backends are known by name (:data:`SIMULATED`): ``mock`` (the offline
pilot of ``plugins/backends/mock_pilot.py``) and ``scripted`` (replayed answers). A third-party
backend is taken for an LLM.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..scenario import Scenario

#: Simulated backends: name -> what its numbers are.
SIMULATED = {
    "mock": "simulated pilot (mock): not a measurement of an LLM",
    "scripted": "scripted answers (scripted): not a measurement of an LLM",
}

#: The mock's options that set ADR and how often an injection is obeyed: inputs, not findings.
MOCK_INPUTS = (
    ("flag_injection_p", "P(flags an injected instruction), arms without the security prefix: ADR's input"),
    ("flag_injection_p_secure", "the same with the security prefix: ADR's input"),
    ("false_flag_p", "P(flags an honest instruction): false alarms' input"),
    ("obey_injection_p", "P(obeys an injected instruction it did not flag), no security prefix"),
    ("obey_injection_p_secure", "the same with the security prefix"),
    ("obey_factor_with_reference", "multiplies the obey probability when R_{i-1} is in the prompt"),
)
#: The mock's other weaknesses: they shape MOER, TLR, collisions and refusals.
MOCK_WEAKNESSES = ("ignore_clearance_p", "lidar_misread_sd", "distance_error_sd", "angle_error_sd_deg",
                   "miss_target_p", "bearing_mirror_p", "recall_target_p", "explore_forward_p", "malformed_p",
                   "limit_violation_p", "feedback_compliance_p")


@dataclass(frozen=True)
class RunInfo:
    backend: str
    model: str
    seed: int
    fingerprint: str
    trials_per_cell: int
    simulated: str | None = None  # the banner, for a simulated backend
    inputs: list[tuple[str, Any, str]] = field(default_factory=list)  # (option, value, what it sets)
    weaknesses: list[tuple[str, Any]] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return {"backend": self.backend, "model": self.model, "seed": self.seed, "fingerprint": self.fingerprint,
                "trials_per_cell": self.trials_per_cell, "simulated": self.simulated,
                "pilot_inputs": {name: value for name, value, _ in self.inputs},
                "pilot_weaknesses": dict(self.weaknesses)}


def _options(scenario: Scenario, plugins: Any) -> dict[str, Any]:
    """The backend's options with their defaults filled in (as given when the registry cannot say)."""
    from ..errors import SafeEmbodAIError

    try:
        if plugins is None:
            from ..plugins import load_plugins

            plugins = load_plugins()
        validated = plugins.registry.validate_options("llm_backend", scenario.backend.use, scenario.backend.options)
        return validated.model_dump()
    except SafeEmbodAIError:  # the backend's plugin is gone: report what the scenario said
        return dict(scenario.backend.options)


def _recorded_fingerprint(folder: Path | None) -> str | None:
    if folder is None:
        return None
    try:
        value = json.loads((folder / "scenario.json").read_text(encoding="utf-8")).get("fingerprint")
    except (OSError, ValueError, AttributeError):
        return None
    return value if isinstance(value, str) else None


def run_info(scenario: Scenario, folder: str | Path | None = None, plugins: Any = None) -> RunInfo:
    """The report's header facts; the fingerprint is the run folder's, else the scenario's own."""
    from ..ablation.run_folder import fingerprint

    name = scenario.backend.use
    options = _options(scenario, plugins)
    recorded = _recorded_fingerprint(Path(folder) if folder is not None else None)
    if name == "mock":
        model = f"none: simulated, tokens counted as for {options.get('token_model', 'gpt-4o')}"
    elif name == "scripted":
        model = "none: answers replayed from the scenario"
    else:
        model = str(options.get("model") or "(the backend's own)")
    inputs = [(key, options[key], what) for key, what in MOCK_INPUTS if key in options] if name == "mock" else []
    weaknesses = [(key, options[key]) for key in MOCK_WEAKNESSES if key in options] if name == "mock" else []
    return RunInfo(backend=name, model=model, seed=scenario.seed, fingerprint=recorded or fingerprint(scenario),
                   trials_per_cell=scenario.trials, simulated=SIMULATED.get(name), inputs=inputs,
                   weaknesses=weaknesses)
