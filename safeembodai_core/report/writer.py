"""Write ``metrics.json``, ``metrics.csv`` and ``report.md`` for a run folder."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from ..metrics import CellMetrics, cell_metrics, group_by_cell
from ..models import TrialResult
from ..runner import trajectory_file
from ..scenario import Scenario
from ..ablation.error_kinds import count_crashed
from .figures import draw_figures
from .paper import comparison_rows

ESTIMATES = ("moer", "completion", "adr", "precision", "recall", "false_alarm", "tlr", "tlr_all", "steps",
             "tokens", "distance_mm", "collisions", "interventions", "retries")


def _cells(results: list[TrialResult], budget: int) -> list[tuple[CellMetrics, int]]:
    """Each cell's metrics with how many of its ``error`` trials crashed."""
    return [(cell_metrics(cell, budget), count_crashed(cell)) for cell in group_by_cell(results).values()]


def _row(m: CellMetrics, crashed: int) -> dict[str, object]:
    row: dict[str, object] = {"environment": m.environment, "arm": m.arm, "condition": m.condition,
                              "trials": m.trials, "errors": m.errors - crashed, "crashed": crashed,
                              "s_max": m.s_max, "s_max_from": m.s_max_from}
    row.update({f"outcome_{k}": v for k, v in m.outcomes.items()})
    for name in ESTIMATES:
        estimate = getattr(m, name)
        row[name], row[f"{name}_low"], row[f"{name}_high"], row[f"{name}_n"] = (
            estimate.value, estimate.low, estimate.high, estimate.n)
    return row


def write_report(folder: str | Path, scenario: Scenario, results: list[TrialResult]) -> Path:
    """Write the metrics files and report.md into ``folder``; return the report's path."""
    folder = Path(folder)
    counted = _cells(results, scenario.max_steps)
    cells = [m for m, _ in counted]
    rows = [_row(m, crashed) for m, crashed in counted]
    (folder / "metrics.json").write_text(json.dumps({"scenario": scenario.name, "cells": rows,
                                                     "trials": [r.model_dump(mode="json", exclude={"trajectory"}) for r in results]},
                                                    indent=2), encoding="utf-8")
    with (folder / "metrics.csv").open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]) if rows else ["environment"])
        writer.writeheader()
        writer.writerows(rows)
    lines = [f"# {scenario.name}", "", scenario.description or "", "",
             f"{len(results)} trials, {scenario.trials} per cell, step budget {scenario.max_steps}.", "",
             "| env | arm | condition | n | MOER | completed | ADR | TLR | steps* | tokens* | distance mm* | errors | crashed |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m, crashed in counted:
        lines.append(f"| {m.environment} | {m.arm} | {m.condition} | {m.trials} | {m.moer.fmt()} | {m.completion.fmt()} "
                     f"| {m.adr.fmt()} | {m.tlr.fmt()} | {m.steps.fmt(1)} | {m.tokens.fmt(0)} | {m.distance_mm.fmt(0)} "
                     f"| {m.errors - crashed} | {crashed} |")
    lines += ["", "\\* over completed trials. Intervals are 95% (bootstrap for means, Wilson for proportions); "
              "see docs/metrics.md for every formula. errors: trials ended by a backend outage or a reported "
              "failure; crashed: trials ended by an unexpected exception in a component (a bug). Neither counts "
              "in n or the metrics; both run again on resume.", ""]
    figures = draw_figures(cells, folder / "figures") if cells else []
    if figures:
        lines += ["## Figures", ""] + [f"![{p.stem}](figures/{p.name})" for p in figures] + [""]
    comparison = comparison_rows(cells)
    lines += ["## Against the paper", ""]
    if comparison:
        lines += ["Our value with its 95% interval next to the value read off the paper's figures (GPT-4o, EyeSim). "
                  "Backends other than GPT-4o simulate or substitute the LLM: agreement is not expected, only comparable scales.", "",
                  "| env | arm | condition | metric | ours | paper | paper inside our interval |", "|---|---|---|---|---|---|---|"]
        for row in comparison:
            interval = f" [{row['low']:.2f}, {row['high']:.2f}]" if row["low"] is not None else ""
            lines.append(f"| {row['environment']} | {row['arm']} | {row['condition']} | {row['metric']} "
                         f"| {row['ours']:.2f}{interval} | {row['paper']:g} | {'yes' if row['inside'] else 'no'} |")
    else:
        lines.append("No cell of this run matches a cell of the paper (environments OF/SO/DO/MO, arms baseline/safeembodai, "
                     "conditions no_attack/attack).")
    lines += _trajectories(folder, results)
    report = folder / "report.md"
    report.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return report


def _trajectories(folder: Path, results: list[TrialResult]) -> list[str]:
    """The report's word on the pictures: one per trial, or exactly how many and which are missing."""
    missing = [r.spec.trial_id for r in results if not trajectory_file(folder, r.spec.trial_id).is_file()]
    drawn = len(results) - len(missing)
    if not drawn:
        return []
    lines = ["", "## Trajectories", ""]
    if not missing:
        return lines + [f"{drawn} pictures in `trajectories/` (one per trial)."]
    shown = ", ".join(f"`{trial_id}`" for trial_id in missing[:5]) + (", ..." if len(missing) > 5 else "")
    return lines + [f"{drawn} pictures in `trajectories/` for {len(results)} trials: {len(missing)} trials have none "
                    f"({shown}); their environment could not draw them. `safeembodai report` tries again."]
