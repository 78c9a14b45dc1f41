"""``safeembodai report RUN_DIR``: metrics, figures and report.md for a (finished or partial) run."""

from __future__ import annotations

import click


@click.command("report")
@click.argument("run_dir", type=click.Path(file_okay=False, exists=True))
def report(run_dir: str) -> None:
    """Write report.md, figures/, metrics.csv and metrics.json for RUN_DIR."""
    from rich.console import Console

    from ..ablation import RunFolder
    from ..errors import SafeEmbodAIError
    from ..plugins import load_plugins
    from ..report import write_report
    from ..runner import ScenarioRunner
    from .summary import summary_table

    folder = RunFolder(run_dir)
    scenario = folder.scenario()
    runner = ScenarioRunner(scenario, load_plugins(), run_dir=folder.path)
    try:
        try:
            results = runner.state.results()
        except NotImplementedError:
            raise SafeEmbodAIError(f"state store {scenario.state.use!r} of {run_dir} keeps no results to report") from None
    finally:
        runner.close()
    if not results:
        raise SafeEmbodAIError(f"{run_dir} has no finished trial yet")
    results = runner.in_trial_order(results)
    console = Console()
    console.print(summary_table(scenario, results))
    console.print(f"report: {write_report(folder.path, scenario, results)}")
