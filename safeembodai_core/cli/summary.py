"""The terminal summary of an ablation: the paper's metrics per cell with 95% intervals."""

from __future__ import annotations

from collections import defaultdict

from rich.table import Table

from ..metrics import cell_metrics
from ..models import TrialResult
from ..scenario import Scenario


def by_cell(results: list[TrialResult]) -> dict[tuple[str, str, str], list[TrialResult]]:
    cells: dict[tuple[str, str, str], list[TrialResult]] = defaultdict(list)
    for result in results:
        cells[(result.spec.environment, result.spec.arm, result.spec.condition)].append(result)
    return cells


def summary_table(scenario: Scenario, results: list[TrialResult]) -> Table:
    table = Table(title=f"{scenario.name}: metrics per cell (95% intervals)", show_lines=False)
    for column in ("env", "arm", "condition", "n", "MOER", "completed", "ADR", "TLR", "steps*", "tokens*",
                   "interventions", "errors"):
        table.add_column(column, overflow="fold")
    for (env, arm, condition), cell in by_cell(results).items():
        m = cell_metrics(cell, scenario.max_steps)
        table.add_row(env, arm, condition, str(m.trials), m.moer.fmt(), m.completion.fmt(), m.adr.fmt(),
                      m.tlr.fmt(), m.steps.fmt(1), m.tokens.fmt(0), m.interventions.fmt(1), str(m.errors))
    table.caption = "* over completed trials"
    return table
