"""A run's cells as the report and the terminal summary show them: metrics scored with the
scenario's own ``metrics`` settings, and what ended each ``error`` trial."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..ablation.error_kinds import error_kind
from ..metrics import CellMetrics, cell_metrics, group_by_cell
from ..models import TrialResult
from ..scenario import Scenario


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


def attacked(scenario: Scenario, condition: str) -> bool:
    """Whether ``condition`` has an attacker (a condition the scenario no longer names counts as attacked)."""
    known = scenario.conditions.get(condition)
    return known is None or bool(known.attackers)


def scenario_cells(scenario: Scenario, results: list[TrialResult]) -> list[Cell]:
    """Every cell of ``results`` in first-seen order, scored with ``scenario.metrics``."""
    cells = []
    for (_, _, condition), cell in group_by_cell(results).items():
        kinds: dict[str, int] = {}
        for result in cell:
            kind = error_kind(result)
            if kind is not None:
                kinds[kind] = kinds.get(kind, 0) + 1
        metrics = cell_metrics(cell, scenario.max_steps, settings=scenario.metrics,
                               attacked=attacked(scenario, condition))
        cells.append(Cell(metrics, cell, kinds))
    return cells
