"""When an attacker strikes: the built-in attackers' schedule, for third-party attackers too.

Every built-in attacker's options model subclasses :class:`AttackSchedule`, and every built-in
attacker asks :meth:`AttackSchedule.fires` whether to attack the step. A third-party attacker
does the same and gets the same options (``rate``, ``start_step``, ``steps``) and the same
pairing across arms::

    class HijackOptions(AttackSchedule):          # extra="forbid" is inherited
        goal: str = "the blue door"

    class GoalHijack(Attacker):
        def __init__(self, options):
            self.options = options

        def attack(self, target):
            if not self.options.fires(target):    # draws one number from target.rng, always
                return []
            ...

**Pairing.** ``fires`` draws exactly one number from the step's stream whatever it decides, and
that stream depends only on the trial seed, the attacker's key and the step (never on the arm),
so every arm of an ablation is attacked at the same steps; a higher ``rate`` only adds attacked
steps. Draw anything else you need after ``fires``, the same count whether or not it fired.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Sequence

from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

from .. import seeds

if TYPE_CHECKING:
    import numpy as np

    from .components import Attacker, AttackSurface
    from ..models import AttackRecord


def attack_stream(seed: int, key: str, step: int) -> "np.random.Generator":
    """The random stream attacker ``key`` draws from at ``step`` of the trial seeded ``seed`` -- the
    pairing rule (module docstring): never the arm. ``key`` "" is the surface's own before any attacker."""
    return seeds.rng(seed, "attacker", key, step)


def run_attackers(surface: "AttackSurface", attackers: Sequence[tuple[str, "Attacker"]], seed: int,
                  step: int) -> "list[AttackRecord]":
    """Let every attacker at ``surface`` in turn, each with its own :func:`attack_stream`; their records,
    tagged with the attacker's key. The one way the trial loop, ``fresh_scan`` and the Gymnasium env
    attack a step, so that they attack alike."""
    records: "list[AttackRecord]" = []
    for key, attacker in attackers:
        surface.rng = attack_stream(seed, key, step)
        records.extend(record.model_copy(update={"attacker": key}) for record in attacker.attack(surface))
    return records


class AttackSchedule(BaseModel):
    """Options saying which steps an attacker strikes; subclass it for your attacker's options."""

    model_config = ConfigDict(extra="forbid")

    rate: float = Field(0.5, ge=0.0, le=1.0, allow_inf_nan=False, description=(
        "probability that a step is attacked (default: the authors' release's injection rate; the paper gives none)"))
    start_step: int = Field(1, ge=1, description="first step that may be attacked")
    steps: list[int] | None = Field(None, description=(
        "attack exactly these steps (then rate and start_step must not be given)"))

    @field_validator("steps")
    @classmethod
    def _positive(cls, steps: list[int] | None) -> list[int] | None:
        if steps is not None and any(s < 1 for s in steps):
            raise ValueError("steps are numbered from 1")
        return steps

    @model_validator(mode="after")
    def _one_schedule(self) -> "AttackSchedule":
        given = sorted({"rate", "start_step"} & self.model_fields_set)
        if self.steps is not None and given:
            raise ValueError(f"give either steps or {' and '.join(given)}, not both: "
                             "steps lists the attacked steps exactly, so the other would be ignored")
        return self

    def scheduled(self, step: int, roll: float) -> bool:
        """Whether ``step`` is attacked given a uniform ``roll`` in [0, 1): listed in ``steps``,
        or else from ``start_step`` on when ``roll < rate``."""
        if self.steps is not None:
            return step in self.steps
        return step >= self.start_step and roll < self.rate

    def fires(self, surface: "AttackSurface") -> bool:
        """Whether to attack ``surface.step``; draws one number from ``surface.rng`` every time."""
        return self.scheduled(surface.step, float(surface.rng.random()))


__all__ = ["AttackSchedule"]
