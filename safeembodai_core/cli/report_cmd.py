"""``safeembodai report RUN_DIR``: metrics, figures and report.md for a (finished or partial) run.

A run that an ``ablate`` is still working on is refused (that run writes its own report when it
ends). Pictures missing from ``trajectories/`` (a run killed between storing a result and
saving its picture) are drawn again from the recorded trajectories first; the report says how
many pictures there are when some are still missing.
"""

from __future__ import annotations

import click


@click.command("report")
@click.argument("run_dir", type=click.Path(file_okay=False, exists=True))
def report(run_dir: str) -> None:
    """Write report.md, figures/, metrics.csv and metrics.json for RUN_DIR."""
    from rich.console import Console
    from rich.markup import escape

    from ..ablation import RunFolder
    from ..runs.folder import RunInProgress, RunLock
    from ..errors import SafeEmbodAIError
    from ..plugin.manager import load_plugins
    from ..report import write_report
    from ..report.run_info import run_info
    from ..runs.runner import ScenarioRunner
    from .summary import summary_table

    folder = RunFolder(run_dir)
    scenario = folder.scenario()
    lock = RunLock(folder.path, wait_s=0.0)
    try:
        lock.acquire()
    except RunInProgress as busy:
        raise SafeEmbodAIError(f"run in progress: {busy}; "
                               "'safeembodai ablate' writes the report when it ends") from None
    try:
        plugins = load_plugins()
        runner = ScenarioRunner(scenario, plugins, run_dir=folder.path, save_trajectories=True)
        try:
            try:
                results = runner.state.results()
            except NotImplementedError:
                raise SafeEmbodAIError(f"state store {scenario.state.use!r} of {run_dir} "
                                       "keeps no results to report") from None
            if not results:
                raise SafeEmbodAIError(f"{run_dir} has no finished trial yet")
            results = runner.in_trial_order(results)
            runner.draw_missing_trajectories(results)
            info = run_info(scenario, folder.path, plugins, results)
            report = write_report(folder.path, scenario, results, store=runner.state, plugins=plugins)
        finally:
            runner.close()
        console = Console(emoji=False)
        console.print(summary_table(scenario, results, info=info))
        console.print(f"report: {escape(str(report))}")
    finally:
        lock.release()
