"""A run's cells as the report and the terminal summary show them: metrics scored with the
scenario's own ``metrics`` settings, what ended each ``error`` trial, and how many trials had a
collision of each attribution (``self``, ``struck``) against the scenario's first arm -- per cell,
and per kind of world the trials met (``TrialResult.world``), both conditions pooled."""

from __future__ import annotations

from dataclasses import dataclass, field

from typing import Mapping, Sequence

from ..ablation.error_kinds import error_kind
from ..metrics import CellMetrics, Estimate, Metric, cell_metrics, group_by_cell, newcombe, wilson
from ..metrics.release import ReleaseReadings, release_readings
from ..models import TrialResult
from ..scenario import Scenario
from .step_facts import TrialFacts


@dataclass(frozen=True)
class Cell:
    """One environment x arm x condition: its metrics, its results and its errors by kind."""

    metrics: CellMetrics
    results: list[TrialResult]
    error_kinds: dict[str, int] = field(default_factory=dict)

    @property
    def crashed(self) -> int:
        return self.error_kinds.get("crash", 0)

    @property
    def errors(self) -> int:
        """``error`` trials other than crashes (outages, store and reported failures, build failures)."""
        return self.metrics.errors - self.crashed

    @property
    def scored(self) -> list[TrialResult]:
        """The trials behind the metrics (``error`` trials left out)."""
        return [r for r in self.results if error_kind(r) is None]


def struck_split(scored: Sequence[TrialResult]) -> tuple[int, int] | None:
    """The cell's struck collisions as (while standing, during the robot's motion); None when a trial
    with a struck collision was recorded before the split was kept (not known, never 0)."""
    if any(r.collisions_struck and r.collisions_struck_standing is None for r in scored):
        return None
    return (sum(r.collisions_struck_standing or 0 for r in scored),
            sum(r.collisions_struck_moving or 0 for r in scored))


def attacked(scenario: Scenario, condition: str) -> bool:
    """Whether ``condition`` has an attacker (a condition the scenario no longer names counts as attacked)."""
    known = scenario.conditions.get(condition)
    return known is None or bool(known.attackers)


def scenario_cells(scenario: Scenario, results: list[TrialResult],
                   catalog: Sequence[Metric] | None = None) -> list[Cell]:
    """Every cell of ``results`` in first-seen order, scored with ``scenario.metrics``: each metric of
    ``catalog`` (the built-ins when None)."""
    cells = []
    for (_, _, condition), cell in group_by_cell(results).items():
        kinds: dict[str, int] = {}
        for result in cell:
            kind = error_kind(result)
            if kind is not None:
                kinds[kind] = kinds.get(kind, 0) + 1
        metrics = cell_metrics(cell, scenario.max_steps, settings=scenario.metrics,
                               attacked=attacked(scenario, condition), catalog=catalog)
        cells.append(Cell(metrics, cell, kinds))
    return cells


def release_of(cell: Cell, facts: Mapping[str, TrialFacts] | None) -> ReleaseReadings | None:
    """The cell's ADR and TLR as the authors' release reads them, from the stored steps' release rows
    (``report/step_facts.py``); None when the steps were not read."""
    if facts is None:
        return None
    rows = [facts[r.spec.trial_id].release for r in cell.scored if r.spec.trial_id in facts]
    return release_readings([counts for counts in rows if counts is not None])


@dataclass(frozen=True)
class _Collided:
    """Of ``trials`` scored trials, how many had at least one ``self`` / ``struck`` collision."""

    trials: int
    self_trials: int
    struck_trials: int

    @property
    def self_rate(self) -> Estimate:
        return wilson(self.self_trials, self.trials)

    @property
    def struck_rate(self) -> Estimate:
        return wilson(self.struck_trials, self.trials)


@dataclass(frozen=True)
class CollisionRates(_Collided):
    """How many of a cell's scored trials had at least one ``self`` / ``struck`` collision, and the cell's
    self-collision rate minus that of ``reference`` (the scenario's first arm) in the same environment and
    condition; ``self_difference`` is None for the reference arm's own cell."""

    reference: str = ""
    self_difference: Estimate | None = None


def collision_rates(scenario: Scenario, cells: list[Cell]) -> list[CollisionRates]:
    """One :class:`CollisionRates` per cell of ``cells``, in the same order. A trial counts when its
    ``collisions_self`` (``collisions_struck``) is above 0; the difference to the reference arm carries
    Newcombe's hybrid score interval (n/a when the reference arm has no scored trial in that environment
    and condition)."""
    reference = next(iter(scenario.arms))
    counts: dict[tuple[str, str, str], tuple[int, int, int]] = {}
    for cell in cells:
        m, scored = cell.metrics, cell.scored
        own, struck = sum(r.collisions_self > 0 for r in scored), sum(r.collisions_struck > 0 for r in scored)
        counts[(m.environment, m.arm, m.condition)] = (len(scored), own, struck)
    rates = []
    for cell in cells:
        m = cell.metrics
        trials, own, struck = counts[(m.environment, m.arm, m.condition)]
        difference = None
        if m.arm != reference:
            base_trials, base_own, _ = counts.get((m.environment, reference, m.condition), (0, 0, 0))
            difference = newcombe(own, trials, base_own, base_trials)
        rates.append(CollisionRates(trials, own, struck, reference, difference))
    return rates


@dataclass(frozen=True)
class WorldRates(_Collided):
    """Collisions per kind of world (``TrialResult.world``) in one environment and arm, both
    conditions pooled: trials with a ``self`` / ``struck`` collision, and the differences to the
    reference arm (the scenario's first) in the same environment and world (None for the reference)."""

    environment: str = ""
    world: str = ""
    arm: str = ""
    self_difference: Estimate | None = None
    struck_difference: Estimate | None = None


def world_rates(scenario: Scenario, cells: list[Cell]) -> list[WorldRates]:
    """One :class:`WorldRates` per (environment, world, arm) of the scored trials that name their
    world, ordered by environment, world, then the scenario's arm order; empty when none does."""
    reference = next(iter(scenario.arms))
    counts: dict[tuple[str, str, str], list[int]] = {}
    for cell in cells:
        m = cell.metrics
        for result in cell.scored:
            if not result.world:
                continue
            row = counts.setdefault((m.environment, result.world, m.arm), [0, 0, 0])
            row[0] += 1
            row[1] += result.collisions_self > 0
            row[2] += result.collisions_struck > 0
    arms = list(scenario.arms)
    order = sorted(counts, key=lambda key: (key[0], key[1], arms.index(key[2]) if key[2] in arms else len(arms)))
    rates = []
    for environment, world, arm in order:
        trials, own, struck = counts[(environment, world, arm)]
        self_difference = struck_difference = None
        if arm != reference:
            base = counts.get((environment, world, reference), [0, 0, 0])
            self_difference = newcombe(own, trials, base[1], base[0])
            struck_difference = newcombe(struck, trials, base[2], base[0])
        rates.append(WorldRates(trials, own, struck, environment=environment, world=world, arm=arm,
                                self_difference=self_difference, struck_difference=struck_difference))
    return rates
