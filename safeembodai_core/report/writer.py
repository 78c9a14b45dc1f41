"""Write ``metrics.json``, ``metrics.csv``, ``figures/`` and ``report.md`` for a run folder.

Cells are scored with the scenario's own ``metrics`` settings (``report/cells.py``); the header
names backend, model, seed, fingerprint and trials per cell, and flags a simulated pilot on the
report and on every figure (``report/run_info.py``); refusals per rule and attacks per kind are
read from the stored steps (``report/step_facts.py``). With ``metrics.release_readings`` the files and
the report add ADR and TLR as the authors' release computes them (``metrics/release.py``) beside ours.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any

from ..contracts.components import StateStore
from ..errors import StateStoreError
from ..logs import get_logger
from ..metrics import Metric, metric_catalog
from ..metrics.release import READINGS, ReleaseReadings
from ..models import TrialResult
from ..runs.runner import trajectory_file
from ..scenario import Scenario
from ..trust.text import csv_cell, json_ready, markdown_code
from . import markdown, step_facts
from .cells import Cell, CollisionRates, collision_rates, release_of, scenario_cells, struck_split, world_rates
from .figures import draw_figures
from .paper import comparison_rows
from .run_info import run_info

log = get_logger(__name__)


def _row(cell: Cell, catalog: tuple[Metric, ...], rates: CollisionRates, facts: dict[str, step_facts.TrialFacts] | None,
         release: ReleaseReadings | None = None, asked: bool = False) -> dict[str, Any]:
    m, scored = cell.metrics, cell.scored
    steps = sum(r.steps for r in scored)
    row: dict[str, Any] = {"environment": m.environment, "arm": m.arm, "condition": m.condition,
                           "trials": m.trials, "errors": cell.errors, "crashed": cell.crashed,
                           "s_max": m.s_max, "s_max_from": m.s_max_from}
    row.update({f"outcome_{k}": v for k, v in m.outcomes.items()})
    row.update({f"errors_{k}": v for k, v in sorted(cell.error_kinds.items())})
    for entry in catalog:
        name, estimate = entry.name, m.estimates[entry.name]
        row[name], row[f"{name}_low"], row[f"{name}_high"], row[f"{name}_n"] = (
            estimate.value, estimate.low, estimate.high, estimate.n)
    row["collisions_self"] = sum(r.collisions_self for r in scored)
    row["collisions_struck"] = sum(r.collisions_struck for r in scored)
    split = struck_split(scored)
    if split is not None:  # left empty where it is not known (runs recorded before it was kept)
        row["collisions_struck_standing"], row["collisions_struck_moving"] = split
    row["trials_collided_self"], row["trials_collided_struck"] = rates.self_trials, rates.struck_trials
    row["self_collision_reference_arm"] = rates.reference
    for name, rate in (("self_collision_rate", rates.self_rate), ("struck_collision_rate", rates.struck_rate),
                       ("self_collision_rate_diff", rates.self_difference)):
        if rate is not None:
            row[name], row[f"{name}_low"], row[f"{name}_high"] = rate.value, rate.low, rate.high
    row["steps_total"], row["attacked_steps"] = steps, sum(r.attacked_steps for r in scored)
    row["attack_rate"] = row["attacked_steps"] / steps if steps else None
    if facts is not None:
        for result in scored:
            trial = facts.get(result.spec.trial_id, step_facts.TrialFacts())
            for rule, count in trial.refusals.items():
                row[f"refusals_{rule}"] = row.get(f"refusals_{rule}", 0) + count
            for kind, count in trial.attacked_by_kind.items():
                row[f"attacked_steps_{kind}"] = row.get(f"attacked_steps_{kind}", 0) + count
    if asked:  # the release's readings, beside ours (None when the stored steps could not be read)
        for name, (attribute, _) in READINGS.items():
            reading = getattr(release, attribute) if release is not None else None
            row[name], row[f"{name}_low"], row[f"{name}_high"], row[f"{name}_n"] = (
                (reading.value, reading.low, reading.high, reading.n) if reading is not None else (None,) * 4)
    return row


def _facts(scenario: Scenario, results: list[TrialResult],
           store: StateStore | None) -> dict[str, step_facts.TrialFacts] | None:
    """What ``store`` counts of the results' trials; None without a store, or one that cannot be read."""
    if store is None:
        return None
    ids = [r.spec.trial_id for r in results]
    release = {r.spec.trial_id: r.outcome for r in results} if scenario.metrics.release_readings else None
    try:
        return step_facts.from_store(store, ids, release)
    except StateStoreError as error:
        log.warning("report.steps_unreadable", store=scenario.state.use, error=str(error))
        return None


def write_report(folder: str | Path, scenario: Scenario, results: list[TrialResult], *,
                 store: StateStore | None = None, plugins: Any = None) -> Path:
    """Write the metrics files, figures and report.md into ``folder``; return the report's path.

    ``store`` (the run's, open) is read for refusals and attack kinds (without one the report
    says they were not read); ``plugins`` (loaded when not given) gives the metric catalog (the
    built-in metrics and the plugins') and fills in the backend's default options.
    """
    folder = Path(folder)
    if plugins is None:
        from ..plugin.manager import load_plugins

        plugins = load_plugins()
    catalog = metric_catalog(plugins)
    info = run_info(scenario, folder, plugins, results)
    cells = scenario_cells(scenario, results, catalog)
    facts = _facts(scenario, results, store)
    rates = collision_rates(scenario, cells)
    asked = scenario.metrics.release_readings
    releases = [release_of(cell, facts) if asked else None for cell in cells]
    rows = [_row(cell, catalog, rate, facts, release, asked) for cell, rate, release in zip(cells, rates, releases)]
    summary: dict[str, object] = {"scenario": scenario.name, "run": info.as_dict(), "cells": rows}
    if asked:
        summary["release_readings"] = {name: f"the authors' release's reading: {source}"
                                       for name, (_, source) in READINGS.items()}
    summary["trials"] = [r.model_dump(mode="json", exclude={"trajectory"}) for r in results]
    (folder / "metrics.json").write_text(json.dumps(json_ready(summary), indent=2, allow_nan=False), encoding="utf-8")
    fields = list(dict.fromkeys(key for row in rows for key in row)) or ["environment"]
    with (folder / "metrics.csv").open("w", newline="", encoding="utf-8") as handle:
        writer = csv.DictWriter(handle, fieldnames=fields)
        writer.writeheader()
        writer.writerows({key: csv_cell(value) for key, value in row.items()} for row in rows)
    metrics = [cell.metrics for cell in cells]
    lines = markdown.header(scenario, info, len(results)) + markdown.spending(results) + markdown.nodes(results)
    lines += (markdown.metrics_table(cells, catalog) + markdown.outcomes_table(cells)
              + markdown.timeouts_line(cells, scenario) + markdown.self_collisions_table(cells))
    lines += markdown.collision_rates_table(cells, rates)
    lines += markdown.world_rates_table(world_rates(scenario, cells), next(iter(scenario.arms)))
    lines += markdown.defences_table(cells, facts, scenario.state.use)
    if asked:
        lines += markdown.release_table(cells, releases, scenario.state.use)
    lines += [markdown.GLOSSARY, ""]
    figures = (draw_figures(metrics, folder / "figures", catalog, note=info.simulated, bars=info.bars())
               if metrics else [])
    if figures:
        lines += ["## Figures", ""] + [f"![{p.stem}](figures/{p.name})" for p in figures] + [""]
    lines += _against_the_paper(metrics, catalog, info.simulated)
    lines += _trajectories(folder, results)
    report = folder / "report.md"
    report.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return report


def _against_the_paper(metrics: list, catalog: tuple[Metric, ...], simulated: str | None) -> list[str]:
    comparison = comparison_rows(metrics, catalog)
    lines = ["## Against the paper", ""]
    if not comparison:
        return lines + ["No cell of this run matches a cell of the paper (environments OF/SO/DO/MO, arms "
                        "baseline/safeembodai, conditions no_attack/attack)."]
    lines += ["Our value with its 95% interval next to the value read off the paper's figures (GPT-4o, EyeSim), "
              "each under the paper's definition: `tlr` is our `tlr_all` (lost steps ÷ all steps). Backends other "
              "than GPT-4o simulate or substitute the LLM: agreement is not expected, only comparable scales."
              + (" This run's pilot is simulated: agreement shows how its configured inputs were calibrated, "
                 "not how an LLM behaves." if simulated else ""), "",
              "| env | arm | condition | metric | ours | paper | paper inside our interval |",
              "|---|---|---|---|---|---|---|"]
    for row in comparison:
        interval = f" [{row['low']:.2f}, {row['high']:.2f}]" if row["low"] is not None else f" (n={row['n']})"
        inside = {True: "yes", False: "no", None: "n/a"}[row["inside"]]
        lines.append(f"{markdown._names(row['environment'], row['arm'], row['condition'])} {row['metric']} "
                     f"| {row['ours']:.2f}{interval} | {row['paper']:g} | {inside} |")
    return lines


def _trajectories(folder: Path, results: list[TrialResult]) -> list[str]:
    """The report's word on the pictures: one per trial, or exactly how many and which are missing."""
    missing = [r.spec.trial_id for r in results if not trajectory_file(folder, r.spec.trial_id).is_file()]
    drawn = len(results) - len(missing)
    if not drawn:
        return []
    lines = ["", "## Trajectories", ""]
    if not missing:
        return lines + [f"{drawn} pictures in `trajectories/` (one per trial)."]
    shown = ", ".join(f"`{markdown_code(trial_id, 200)}`" for trial_id in missing[:5])
    shown += ", ..." if len(missing) > 5 else ""
    return lines + [f"{drawn} pictures in `trajectories/` for {len(results)} trials: {len(missing)} trials have none "
                    f"({shown}); their environment could not draw them. `safeembodai report` tries again."]
