"""The terminal summary of an ablation: the paper's metrics per cell with 95% intervals."""

from __future__ import annotations

from rich.markup import escape
from rich.table import Table

from ..metrics import cell_metrics, group_by_cell
from ..models import TrialResult
from ..ablation.error_kinds import count_crashed
from ..scenario import Scenario


def summary_table(scenario: Scenario, results: list[TrialResult]) -> Table:
    table = Table(title=f"{scenario.name}: metrics per cell", box=None, padding=(0, 1, 0, 0), pad_edge=False,
                  header_style="bold underline")
    crashes = count_crashed(results) > 0  # the column only when needed: the table fits 80 columns
    columns = ("env", "arm", "condition", "n", "MOER", "done", "ADR", "TLR", "steps*", "tokens*", "ref", "err")
    for column in columns + (("crash",) if crashes else ()):
        table.add_column(column, no_wrap=True, justify="left" if column in ("env", "arm", "condition") else "right")
    for (env, arm, condition), cell in group_by_cell(results).items():
        m = cell_metrics(cell, scenario.max_steps)
        crashed = count_crashed(cell)
        table.add_row(escape(env), escape(arm), escape(condition), str(m.trials), _value(m.moer, 2), _value(m.completion, 2), _value(m.adr, 2),
                      _value(m.tlr, 2), _value(m.steps, 1), _value(m.tokens, 0), _value(m.interventions, 1),
                      str(m.errors - crashed), *((str(crashed),) if crashes else ()))
    table.caption = ("done = completed share; * over completed trials; ref = answers refused by a validator per trial;\n"
                     "err = backend or store failures" + ("; crash = trials a component's bug ended (see the log)" if crashes else "")
                     + "; 95% intervals in report.md")
    return table


def _value(estimate, digits: int) -> str:
    return "-" if estimate.value is None else f"{estimate.value:.{digits}f}"
