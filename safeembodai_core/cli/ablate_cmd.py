"""``safeembodai ablate SCENARIO``: every trial of every cell, with progress and a summary."""

from __future__ import annotations

import json
import time
from collections import Counter, defaultdict
from pathlib import Path

import click

from .common import load, scenario_options


@click.command("ablate")
@scenario_options
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Run folder (default: runs/<scenario>-<time>).")
def ablate(scenario_path, backend, seed, overrides, out_dir) -> None:
    """Run the ablation of SCENARIO: environments x arms x conditions x trials."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
    from rich.table import Table

    from ..runner import ScenarioRunner

    scenario, plugins = load(scenario_path, backend, seed, overrides)
    folder = Path(out_dir or Path("runs") / f"{scenario.name}-{time.strftime('%Y%m%d-%H%M%S')}")
    folder.mkdir(parents=True, exist_ok=True)
    runner = ScenarioRunner(scenario, plugins, run_dir=folder)
    specs = runner.specs()
    outcomes: dict[tuple[str, str, str], Counter] = defaultdict(Counter)
    console = Console()
    try:
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeRemainingColumn(),
                      console=console) as progress, (folder / "trials.jsonl").open("a", encoding="utf-8") as sink:
            task = progress.add_task("trials", total=len(specs))
            for spec in specs:
                progress.update(task, description=spec.trial_id)
                result = runner.run(spec)
                sink.write(json.dumps(result.model_dump(mode="json")) + "\n")
                sink.flush()
                outcomes[(spec.environment, spec.arm, spec.condition)][result.outcome.value] += 1
                progress.advance(task)
    finally:
        runner.close()
    table = Table(title=f"{scenario.name}: outcomes per cell")
    kinds = ("completed", "timeout", "interrupted", "safe_abort", "error")
    for column in ("environment", "arm", "condition", *kinds):
        table.add_column(column)
    for (env, arm, condition), counts in outcomes.items():
        table.add_row(env, arm, condition, *(str(counts.get(k, 0)) for k in kinds))
    console.print(table)
    console.print(f"results in {folder / 'trials.jsonl'}")
