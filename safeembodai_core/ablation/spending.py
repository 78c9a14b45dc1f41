"""A spending cap for a run: ``ablate --max-tokens N`` and ``--max-cost USD`` stop it cleanly once the
trials it finished have used that much.

Counted from the trials this invocation finishes (their prompt and completion tokens, retries
included; a trial's replayed answers count as if paid, so the count errs on the safe side), priced
by the backend (:meth:`LLMBackend.cost <safeembodai_core.components.LLMBackend.cost>`: litellm's
list prices). The trials in flight when the cap is reached are cut off; their answered calls are in
the response cache, so ``--resume`` with a higher cap does not pay for them again.
"""

from __future__ import annotations

from typing import Callable

from ..errors import SafeEmbodAIError
from ..models import TrialResult


class SpendingCapReached(SafeEmbodAIError):
    """The run used what ``--max-tokens`` or ``--max-cost`` allowed."""


class SpendingCap:
    """What a run may use: ``max_tokens`` tokens, ``max_cost`` US dollars at ``price(prompt, completion)``."""

    def __init__(self, max_tokens: int | None = None, max_cost: float | None = None,
                 price: Callable[[int, int], float | None] | None = None) -> None:
        if max_cost is not None and (price is None or price(1000, 1000) is None):
            raise SafeEmbodAIError("--max-cost needs the model's price, and this backend knows none "
                                   "(a simulated pilot or a model litellm has no price for): use --max-tokens")
        self.max_tokens, self.max_cost, self.price = max_tokens, max_cost, price
        self.tokens, self.cost = 0, 0.0

    def add(self, result: TrialResult) -> None:
        """Count a finished trial; raise :class:`SpendingCapReached` once a cap is reached."""
        self.tokens += result.prompt_tokens + result.completion_tokens
        if self.max_cost is not None and self.price is not None:
            self.cost += self.price(result.prompt_tokens, result.completion_tokens) or 0.0
        if self.max_tokens is not None and self.tokens >= self.max_tokens:
            raise SpendingCapReached(f"--max-tokens {self.max_tokens} reached: the finished trials used "
                                     f"{self.tokens} tokens")
        if self.max_cost is not None and self.cost >= self.max_cost:
            raise SpendingCapReached(f"--max-cost {self.max_cost:g} reached: the finished trials cost "
                                     f"${self.cost:.4f} at the model's list price")
