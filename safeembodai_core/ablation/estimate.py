"""What a run will cost, before it runs: ``ablate --dry-run``.

Calls: every trial makes at least one call; a trial that uses its whole step budget makes
``max_steps`` calls, and ``max_steps × (failure_threshold + 1)`` if Algorithm 1 refuses every
answer but the last (every arm retries an answer that does not parse). Tokens per
call are measured, not assumed: one step of each environment × arm is run with the offline mock
pilot (the real world, perception and prompt; nothing is sent anywhere), and the prompt it was
given is counted as the mock counts it (litellm's gpt-4o tokenizer, images by their detail). The
answer's tokens are the mock's, which writes about what a model writes; a model that reasons at
length costs more. Prices, where the scenario's backend knows one, are its list prices
(:meth:`LLMBackend.cost <safeembodai_core.contracts.components.LLMBackend.cost>`).
"""

from __future__ import annotations

from dataclasses import dataclass

from ..errors import SafeEmbodAIError
from ..models import Outcome, TrialSpec
from ..plugin.manager import Plugins
from ..scenario import Scenario
from ..plugin.refs import ComponentRef


@dataclass(frozen=True)
class CellEstimate:
    """One environment × arm: its trials, the calls they may make and one call's measured tokens."""

    environment: str
    arm: str
    trials: int
    calls_min: int
    calls_budget: int
    calls_max: int
    prompt_tokens: int
    completion_tokens: int


def estimate(scenario: Scenario, plugins: Plugins, pending: list[TrialSpec]) -> list[CellEstimate]:
    """The calls and tokens of ``pending`` trials, per environment × arm (see the module docstring)."""
    from ..runs.runner import ScenarioRunner, trial_spec

    probe = scenario.model_copy(update={"max_steps": 1, "backend": ComponentRef(use="mock"),
                                        "state": ComponentRef(use="memory")})
    runner = ScenarioRunner(probe, plugins)
    rows = []
    try:
        for environment, arm in dict.fromkeys((s.environment, s.arm) for s in pending):
            trials = [s for s in pending if (s.environment, s.arm) == (environment, arm)]
            condition = trials[0].condition
            result = runner.run(trial_spec(probe, environment, arm, condition, trials[0].index))
            if result.outcome == Outcome.ERROR:
                raise SafeEmbodAIError(f"--dry-run: the probe step of {environment}/{arm} failed: {result.detail}")
            calls = max(1, result.steps + result.retries)
            tries = scenario.arms[arm].failure_threshold + 1  # every arm retries an answer that does not parse
            rows.append(CellEstimate(environment, arm, len(trials), len(trials), len(trials) * scenario.max_steps,
                                     len(trials) * scenario.max_steps * tries,
                                     round(result.prompt_tokens / calls), round(result.completion_tokens / calls)))
    finally:
        runner.close()
    return rows
