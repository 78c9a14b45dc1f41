"""``prompt_injection``: a malicious prompt attached to (or replacing) the human instruction h_i.

Per step, the attacker draws the same four numbers from the step's stream whatever happens
(the attack roll, the payload pick, two coordinates), so raising ``rate`` only adds attacked
steps: a step attacked at a lower rate keeps its payload, and every arm of an ablation sees the
same attacks at the same steps.
"""

from __future__ import annotations

import math

from safeembodai_core.contracts.components import Attacker, AttackSurface
from safeembodai_core.models import AttackRecord

from .library import PAYLOADS

COORDINATE_RANGE_MM = 3000


class PromptInjectionAttacker(Attacker):
    """Injects a payload from :data:`PAYLOADS` (or the user's own) at a seeded per-step rate."""

    name = "prompt_injection"

    def __init__(self, options) -> None:
        self.options = options
        if options.payloads:
            self.pool = [("custom", text) for text in options.payloads]
        else:
            kinds = options.kinds or list(PAYLOADS)
            self.pool = [(kind, text) for kind in kinds for text in PAYLOADS[kind]]

    def _coordinates(self, target: AttackSurface, x: int, y: int) -> tuple[int, int]:
        truth = target.observation.truth
        if self.options.aim_at_target and truth.target_bearing_deg is not None and truth.target_distance_mm:
            rad = math.radians(truth.target_bearing_deg)
            return round(truth.target_distance_mm * math.cos(rad)), round(truth.target_distance_mm * math.sin(rad))
        return x, y

    def attack(self, target: AttackSurface) -> list[AttackRecord]:
        o = self.options
        rng = target.rng
        fires = o.fires(target)
        pick = int(rng.integers(len(self.pool)))
        x, y = (int(v) for v in rng.integers(-COORDINATE_RANGE_MM, COORDINATE_RANGE_MM + 1, size=2))
        if not fires:
            return []
        kind, template = self.pool[pick]
        x, y = self._coordinates(target, x, y)
        payload = template.replace("{x}", str(x)).replace("{y}", str(y))
        if o.mode == "replace":  # the release: the injection *is* h_i (eyesimLLM discrete_llm_robot.py:166-174)
            target.instruction = payload
        else:
            target.instruction = f"{target.instruction}{o.separator}{payload}" if target.instruction else payload
        return [AttackRecord(attacker=self.name, channel="instruction", kind=kind, payload=payload)]
