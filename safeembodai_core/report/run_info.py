"""What a report says before any number: which backend and model, which seed, which scenario
(its fingerprint), how many trials per cell -- and, for a simulated pilot, that it is one and which
of its options are the inputs behind the numbers that look like findings.

The built-in simulated backends are known by name (:data:`SIMULATED`): ``mock`` (the offline
pilot of ``plugins/backends/mock/``) and ``scripted`` (replayed answers). A third-party
backend is taken for an LLM.

The model of litellm's backends (:data:`LITELLM_BACKENDS`) is their ``model`` option, a litellm
id ``<route>/<model>``: the report names the model without litellm's provider route
(``openai/local`` is the model ``local`` behind an OpenAI-compatible server) and says so. The
name a server reports in its replies is not part of the stored records, so it cannot be named.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..scenario import Scenario

#: Simulated backends: name -> what its numbers are.
SIMULATED = {
    "mock": "simulated pilot (mock): not a measurement of an LLM",
    "scripted": "scripted answers (scripted): not a measurement of an LLM",
}

#: Backends whose ``model`` option is a litellm model id (``plugins/backends/litellm/``).
LITELLM_BACKENDS = ("gpt-4o", "litellm", "local")
#: litellm provider routes a model id may start with (``openai/`` reaches any OpenAI-compatible server).
ROUTES = frozenset({
    "openai", "azure", "azure_ai", "anthropic", "bedrock", "vertex_ai", "gemini", "mistral", "cohere", "groq",
    "together_ai", "fireworks_ai", "deepinfra", "deepseek", "openrouter", "perplexity", "xai", "huggingface",
    "ollama", "ollama_chat", "hosted_vllm", "vllm", "lm_studio", "llamafile", "openai_like", "custom_openai",
    "text-completion-openai", "litellm_proxy", "nvidia_nim", "cerebras", "sambanova", "watsonx", "databricks",
    "sagemaker", "replicate", "cloudflare", "github", "xinference", "oobabooga", "docker_model_runner",
})

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
    model_id: str | None = None  # the backend's model option as configured (a litellm id), when it has one
    model_source: str | None = None  # how ``model`` was read off the configuration (litellm's backends)
    inputs: list[tuple[str, Any, str]] = field(default_factory=list)  # (option, value, what it sets)
    weaknesses: list[tuple[str, Any]] = field(default_factory=list)

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
            return f"{self.simulated.split(':')[0]}, not an LLM"
        return f"{self.backend}/{self.model}"

    def bars(self) -> str:
        """What a figure's bars show: who answered and the trials per cell."""
        return f"bars: {self.pilot}, N = {self.trials_per_cell} trials per cell"


def model_without_route(model_id: str) -> tuple[str, str | None]:
    """A litellm model id split into the model and litellm's provider route (None when it names none)."""
    route, _, rest = model_id.partition("/")
    if rest and route in ROUTES:
        return rest, route
    return model_id, None


def _litellm_model(options: dict[str, Any]) -> tuple[str, str | None, str]:
    """(model, configured id, where the model comes from) of one of litellm's backends."""
    model_id = str(options.get("model") or "")
    if not model_id:
        return "(the backend's own)", None, "no model configured"
    model, route = model_without_route(model_id)
    unreported = "no reply named a model (or the run's results were not read)"
    if route is None:
        return model, model_id, f"as configured; {unreported}"
    return model, model_id, f"the configured litellm id `{model_id}` without its route `{route}/`; {unreported}"


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
    from ..ablation.run_folder import RunFolder
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
    With ``results``, an LLM's model is the one its replies named (litellm's backends)."""
    from ..ablation.run_folder import fingerprint

    name = scenario.backend.use
    options = _options(scenario, plugins)
    recorded = _recorded_fingerprint(Path(folder) if folder is not None else None)
    model_id = source = None
    if name == "mock":
        model = f"none: simulated, tokens counted as for {options.get('token_model', 'gpt-4o')}"
    elif name == "scripted":
        model = "none: answers replayed from the scenario"
    elif name in LITELLM_BACKENDS:
        model, model_id, source = _litellm_model(options)
        named = _answered_by(results)
        if named:
            model = ", ".join(named[:3])
            source = f"as the server named it in its replies (configured: `{model_id or 'none'}`)"
    else:
        model = str(options.get("model") or "(the backend's own)")
    inputs = [(key, options[key], what) for key, what in MOCK_INPUTS if key in options] if name == "mock" else []
    weaknesses = [(key, options[key]) for key in MOCK_WEAKNESSES if key in options] if name == "mock" else []
    return RunInfo(backend=name, model=model, seed=scenario.seed, fingerprint=recorded or fingerprint(scenario),
                   trials_per_cell=scenario.trials, simulated=SIMULATED.get(name), model_id=model_id,
                   model_source=source, inputs=inputs, weaknesses=weaknesses)
