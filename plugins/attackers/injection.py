"""The prompt-injection attacker."""

from __future__ import annotations

from safeembodai_core.components import Attacker, AttackSurface
from safeembodai_core.models import AttackRecord

from .library import PAYLOADS


class PromptInjectionAttacker(Attacker):
    name = "prompt_injection"

    def __init__(self, options) -> None:
        self.options = options
        if options.payloads:
            self.pool = [("custom", text) for text in options.payloads]
        else:
            kinds = options.kinds or list(PAYLOADS)
            self.pool = [(kind, text) for kind in kinds for text in PAYLOADS[kind]]

    def attack(self, target: AttackSurface) -> list[AttackRecord]:
        o = self.options
        rng = target.rng
        # draw every number first so the decision and the payload never depend on each other
        roll, pick, x, y = rng.random(), int(rng.integers(len(self.pool))), int(rng.integers(0, 4000)), int(rng.integers(0, 4000))
        if target.step < o.start_step or roll >= o.rate:
            return []
        kind, template = self.pool[pick]
        payload = template.replace("{x}", str(x)).replace("{y}", str(y))
        target.instruction = payload if o.mode == "replace" else f"{target.instruction} {payload}".strip()
        return [AttackRecord(attacker=self.name, channel="instruction", kind=kind, payload=payload)]
