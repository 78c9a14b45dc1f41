"""The guarded loop around your own parts: one trial of Algorithm 1 with your environment and backend.

For agent projects that ``import safeembodai_core``: components may be given as objects or as registered
names (with options), and are built as a scenario builds them. See ``docs/library.md``.
"""

from __future__ import annotations

from typing import Any, Sequence

from ..contracts.components import Environment, LLMBackend
from ..models import DEFAULT_LIMITS, ControlLimits, StepRecord, TrialResult, TrialSpec
from ..models.prompt import DEFAULT_INSTRUCTION
from ..plugin.building import build_components
from ..plugin.manager import Plugins, load_plugins
from .defences import Defences
from .trial import LoopSettings, TrialParts, run_trial


def run_guarded_trial(
    environment: Environment | str | dict[str, Any],
    backend: LLMBackend | str | dict[str, Any],
    *,
    defences: Defences | dict[str, Any] | None = None,
    seed: int = 0,
    max_steps: int = 20,
    instruction: str | None = None,
    perception: Any = "images",
    prompt_builder: Any = "jinja",
    state: Any = "memory",
    attackers: Sequence[Any] = (),
    limits: ControlLimits = DEFAULT_LIMITS,
    plugins: Plugins | None = None,
    trial_id: str = "trial",
) -> tuple[TrialResult, list[StepRecord]]:
    """Run one guarded trial around your own parts; return the result and every step record.

    Validators come from ``defences.validators`` (names and options, as in a scenario) and run
    only when ``defences.safety_validation`` is on. Components named here are built as a
    scenario builds them: ``BuildContext.seed`` is ``seed`` (0 for the environment, which gets
    ``seed`` in ``reset``, and the state store, which outlives trials).
    """
    plugins = plugins or load_plugins()
    defences = defences if isinstance(defences, Defences) else Defences.model_validate(defences or {})

    def one(kind: str, item: Any, seed: int = seed) -> Any:
        return build_components(plugins, kind, [item], seed)[0][1]

    parts = TrialParts(
        environment=one("environment", environment, 0),
        perception=one("perception", perception),
        prompt_builder=one("prompt_builder", prompt_builder),
        state=one("state_store", state, 0),
        backend=one("llm_backend", backend),
        validators=build_components(plugins, "validator", defences.validators, seed),
        attackers=build_components(plugins, "attacker", attackers, seed),
    )
    settings = LoopSettings(max_steps=max_steps, defences=defences, limits=limits,
                            instruction=instruction or DEFAULT_INSTRUCTION)
    spec = TrialSpec(trial_id=trial_id, environment=type(parts.environment).__name__, arm="custom",
                     condition="custom", seed=seed)
    result = run_trial(spec, parts, settings, plugins)
    return result, parts.state.steps(trial_id)
