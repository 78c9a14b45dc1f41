"""The terminal summary of an ablation: what ran (backend, model, seed, scenario fingerprint, N per
cell, a simulated pilot named as such) and the paper's metrics per cell, scored with the
scenario's ``metrics`` settings."""

from __future__ import annotations

from typing import Any

from rich.table import Table

from ..metrics import metric_catalog
from ..metrics.catalog import CORE
from ..models import TrialResult
from ..report.cells import scenario_cells
from ..report.run_info import RunInfo, run_info
from ..scenario import Scenario
from ..trust.text import terminal_markup


def title(scenario: Scenario, info: RunInfo) -> str:
    """The lines above the table (rich markup, escaped)."""
    lines = [f"{terminal_markup(scenario.name)}: metrics per cell",
             f"backend {terminal_markup(info.backend)}, model {terminal_markup(info.model)}",
             f"seed {info.seed}, scenario {info.fingerprint[:12]}, N={info.trials_per_cell} per cell"]
    if info.simulated:
        lines.append(f"[bold red]{terminal_markup(info.simulated.upper())}[/bold red]")
    return "\n".join(lines)


def summary_table(scenario: Scenario, results: list[TrialResult], *, info: RunInfo | None = None,
                  plugins: Any = None) -> Table:
    if plugins is None:
        from ..plugin.manager import load_plugins

        plugins = load_plugins()
    catalog = metric_catalog(plugins)
    info = info or run_info(scenario, plugins=plugins, results=results)
    table = Table(title=title(scenario, info), box=None, padding=(0, 1, 0, 0), pad_edge=False,
                  header_style="bold underline")
    cells = scenario_cells(scenario, results, catalog)
    crashes = any(cell.crashed for cell in cells)  # the column only when needed: the table fits 80 columns
    shown = [entry for entry in catalog if entry.console]
    columns = ("env", "arm", "condition", "n", *(str(entry.console) for entry in shown), "err")
    for column in columns + (("crash",) if crashes else ()):
        table.add_column(terminal_markup(column), no_wrap=True,
                         justify="left" if column in ("env", "arm", "condition") else "right")
    for cell in cells:
        m = cell.metrics
        table.add_row(terminal_markup(m.environment), terminal_markup(m.arm), terminal_markup(m.condition),
                      str(m.trials),
                      *(_value(m.estimates[entry.name], entry.digits) for entry in shown), str(cell.errors),
                      *((str(cell.crashed),) if crashes else ()))
    table.caption = "\n".join([
        "done = completed share; TLR = lost steps / all steps (the paper's)",
        "* over completed trials; ref = validator refusals per trial",
        "err = backend, store or other failures" + ("; crash = a component's bug" if crashes else ""),
        "n/a = nothing to estimate (ADR without attacks); intervals in report.md",
        *(terminal_markup(f"{entry.console} = {entry.description or entry.name} (plugin {entry.origin})")
          for entry in shown if entry.origin != CORE), *_settings(scenario)])
    return table


def _settings(scenario: Scenario) -> list[str]:
    """Caption lines for metric settings that are not ours by default (the release's, say)."""
    m, lines = scenario.metrics, []
    if m.s_j == "attempts" or not m.cap_s_ratio:
        lines.append("MOER: s_j = " + ("LLM attempts" if m.s_j == "attempts" else "steps")
                     + (", s_j/S_max not capped" if not m.cap_s_ratio else ""))
    if m.release_readings:
        lines.append("ADR precision/recall/F1 and TLR as the release reads them: report.md")
    return lines


def _value(estimate, digits: int) -> str:
    return "n/a" if estimate.value is None else f"{estimate.value:.{digits}f}"
