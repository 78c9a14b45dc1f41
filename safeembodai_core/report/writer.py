"""Write ``metrics.json``, ``metrics.csv`` and ``report.md`` for a run folder."""

from __future__ import annotations

import csv
import json
from pathlib import Path

from ..metrics import CellMetrics, cell_metrics, group_by_cell
from ..models import TrialResult
from ..scenario import Scenario
from .figures import draw_figures
from .paper import comparison_rows

ESTIMATES = ("moer", "completion", "adr", "precision", "recall", "false_alarm", "tlr", "tlr_all", "steps",
             "tokens", "distance_mm", "collisions", "interventions", "retries")


def _cells(results: list[TrialResult], budget: int) -> list[CellMetrics]:
    return [cell_metrics(cell, budget) for cell in group_by_cell(results).values()]


def _row(m: CellMetrics) -> dict[str, object]:
    row: dict[str, object] = {"environment": m.environment, "arm": m.arm, "condition": m.condition,
                              "trials": m.trials, "errors": m.errors, "s_max": m.s_max, "s_max_from": m.s_max_from}
    row.update({f"outcome_{k}": v for k, v in m.outcomes.items()})
    for name in ESTIMATES:
        estimate = getattr(m, name)
        row[name], row[f"{name}_low"], row[f"{name}_high"], row[f"{name}_n"] = (
            estimate.value, estimate.low, estimate.high, estimate.n)
    return row


def write_report(folder: str | Path, scenario: Scenario, results: list[TrialResult]) -> Path:
    """Write the metrics files and report.md into ``folder``; return the report's path."""
    folder = Path(folder)
    cells = _cells(results, scenario.max_steps)
    rows = [_row(m) for m in cells]
    (folder / "metrics.json").write_text(json.dumps({"scenario": scenario.name, "cells": rows,
                                                     "trials": [r.model_dump(mode="json", exclude={"trajectory"}) for r in results]},
                                                    indent=2), encoding="utf-8")
    with (folder / "metrics.csv").open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]) if rows else ["environment"])
        writer.writeheader()
        writer.writerows(rows)
    lines = [f"# {scenario.name}", "", scenario.description or "", "",
             f"{len(results)} trials, {scenario.trials} per cell, step budget {scenario.max_steps}.", "",
             "| env | arm | condition | n | MOER | completed | ADR | TLR | steps* | tokens* | distance mm* | errors |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for m in cells:
        lines.append(f"| {m.environment} | {m.arm} | {m.condition} | {m.trials} | {m.moer.fmt()} | {m.completion.fmt()} "
                     f"| {m.adr.fmt()} | {m.tlr.fmt()} | {m.steps.fmt(1)} | {m.tokens.fmt(0)} | {m.distance_mm.fmt(0)} "
                     f"| {m.errors} |")
    lines += ["", "\\* over completed trials. Intervals are 95% (bootstrap for means, Wilson for proportions); "
              "see docs/metrics.md for every formula.", ""]
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
    trajectories = sorted((folder / "trajectories").glob("*.png")) if (folder / "trajectories").is_dir() else []
    if trajectories:
        lines += ["", "## Trajectories", "", f"{len(trajectories)} pictures in `trajectories/` (one per trial)."]
    report = folder / "report.md"
    report.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return report
