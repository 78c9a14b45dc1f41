"""A spending cap for a run: ``ablate --max-tokens N`` and ``--max-cost USD`` stop it cleanly once the
trials it finished have used that much.

Counted from the trials this invocation finishes (their prompt and completion tokens, retries
included; a trial's replayed answers count as if paid, so the count errs on the safe side), priced
by the backend (:meth:`LLMBackend.cost <safeembodai_core.contracts.components.LLMBackend.cost>`: litellm's
list prices). The trials in flight when the cap is reached are cut off; their answered calls are in
the response cache, so ``--resume`` does not pay for them again. Each invocation counts from zero,
and a run may spend past the cap by what its trials in flight use (up to ``--workers`` ×
``--concurrency`` trials).
"""

from __future__ import annotations

from typing import Any, Callable

from ..errors import SafeEmbodAIError
from ..models import TrialResult


def backend_price(scenario: Any, plugins: Any) -> Callable[[int, int], float | None]:
    """The scenario's backend's :meth:`~safeembodai_core.contracts.components.LLMBackend.cost` (the backend is
    built only to ask it, then closed: a price needs no connection and no key); raises what building raises."""
    from ..plugin.building import ComponentBuilder

    backend = ComponentBuilder(scenario, plugins).backend(only_to_describe=True)
    backend.close()
    return backend.cost


class SpendingCapReached(SafeEmbodAIError):
    """The run used what ``--max-tokens`` or ``--max-cost`` allowed."""


class SpendingCap:
    """What a run may use: ``max_tokens`` tokens, ``max_cost`` US dollars at ``price(prompt, completion)``."""

    def __init__(self, max_tokens: int | None = None, max_cost: float | None = None,
                 price: Callable[[int, int], float | None] | None = None) -> None:
        if max_cost is not None:
            try:
                known = price is not None and price(1000, 1000) is not None
            except Exception as error:  # a plugin's cost() that fails: no price, said plainly
                raise SafeEmbodAIError(f"--max-cost: the backend's price failed ({type(error).__name__}: "
                                       f"{error}): use --max-tokens") from None
            if not known:
                raise SafeEmbodAIError("--max-cost needs the model's price, and this backend knows none "
                                       "(a simulated pilot or a model litellm has no price for): use --max-tokens")
        self.max_tokens, self.max_cost, self.price = max_tokens, max_cost, price
        self.tokens, self.cost = 0, 0.0

    def add(self, result: TrialResult, more: bool = True) -> None:
        """Count a finished trial; raise :class:`SpendingCapReached` once a cap is reached and ``more``
        trials are left to run (a run whose last trial crosses the cap is complete, not stopped).
        A trial's cost is the one it recorded (``TrialResult.cost_usd``), priced again only without one."""
        self.tokens += result.prompt_tokens + result.completion_tokens
        unpriced = False
        if self.max_cost is not None and self.price is not None:
            cost = result.cost_usd
            if cost is None and result.tokens:
                cost = self._priced(result)
                unpriced = cost is None  # unknown is never free: the cap cannot vouch for the next trial
            self.cost += cost or 0.0
        if not more:
            return
        if unpriced:
            raise SpendingCapReached(f"--max-cost {self.max_cost:g}: trial {result.spec.trial_id} has no price "
                                     f"(the backend priced it as unknown), so what the run spent is unknown; "
                                     f"stopped before another trial (the finished ones cost at least "
                                     f"${self.cost:.4f})")
        if self.max_tokens is not None and self.tokens >= self.max_tokens:
            raise SpendingCapReached(f"--max-tokens {self.max_tokens} reached: the finished trials used "
                                     f"{self.tokens} tokens")
        if self.max_cost is not None and self.cost >= self.max_cost:
            raise SpendingCapReached(f"--max-cost {self.max_cost:g} reached: the finished trials cost "
                                     f"${self.cost:.4f} at the model's list price")

    def _priced(self, result: TrialResult) -> float | None:
        """The trial's tokens at the backend's price; None when it has none (or says something
        that is not a price: a failure, NaN, a negative or absurd number)."""
        try:
            cost = self.price(result.prompt_tokens, result.completion_tokens) if self.price is not None else None
        except Exception:  # a plugin's cost() that fails mid-run: no price, which stops the run
            return None
        if isinstance(cost, bool) or not isinstance(cost, (int, float)) or not 0 <= cost <= 1e9:
            return None
        return float(cost)
