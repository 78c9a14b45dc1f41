"""``safeembodai ablate SCENARIO``: every trial of every cell, in parallel, resumable, summarised.

Ctrl-C (SIGINT) and SIGTERM stop the run cleanly: workers are killed, finished trials stay
recorded, the resume command is printed and the exit code is 130 or 143 (128 + the signal).
"""

from __future__ import annotations

import signal

import click

from .common import load, scenario_options


@click.command("ablate")
@scenario_options
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True, help="Trials in parallel.")
@click.option("--executor", type=click.Choice(["serial", "process", "ray"]), default=None,
              help="Where trials run (default: serial for 1 worker, process otherwise).")
@click.option("--address", default=None, help="Ray cluster address (with --executor ray; default: a local Ray).")
@click.option("--out", "out_root", type=click.Path(file_okay=False), default="runs", show_default=True,
              help="Folder that receives the run folder <scenario>-<time>.")
@click.option("--resume", "resume_dir", type=click.Path(file_okay=False, exists=True), default=None,
              help="Finish the missing trials of this run folder (same scenario and overrides).")
@click.option("--no-report", is_flag=True, help="Skip report.md and figures at the end.")
def ablate(scenario_path, backend, seed, overrides, workers, executor, address, out_root, resume_dir, no_report) -> None:
    """Run the ablation of SCENARIO: environments x arms x conditions x trials."""
    from rich.console import Console
    from rich.markup import escape

    from ..ablation import RunFolder
    from ..ablation.lifeline import StopSignals
    from ..errors import SafeEmbodAIError
    from .summary import summary_table

    scenario, plugins = load(scenario_path, backend, seed, overrides)
    folder = RunFolder(resume_dir) if resume_dir else RunFolder.create(out_root, scenario)
    console = Console()
    with StopSignals() as stop:
        try:
            results = _run(console, scenario, plugins, folder, resume_dir is not None, workers, executor, address)
            console.print(summary_table(scenario, results))
            if not no_report:
                from ..report import write_report

                console.print(f"report: {write_report(folder.path, scenario, results)}")
        except (KeyboardInterrupt, SafeEmbodAIError) as error:
            # a signal sent to the whole process group also kills workers: the broken pool is the signal's doing
            if isinstance(error, SafeEmbodAIError) and stop.signum is None:
                raise
            console.print(f"[yellow]interrupted[/yellow] ({signal.Signals(stop.exit_code - 128).name}): "
                          f"finished trials are recorded; resume with --resume {escape(str(folder.path))}")
            raise SystemExit(stop.exit_code) from None
    console.print(f"run folder: {escape(str(folder.path))}")


def _run(console, scenario, plugins, folder, resume, workers, executor, address):
    from rich.markup import escape
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from ..ablation import Ablation

    ablation = Ablation(scenario, plugins, folder, resume=resume, workers=workers, executor=executor, address=address)
    try:
        pending = ablation.pending()
        cells = {(s.environment, s.arm, s.condition) for s in pending}
        console.print(f"run folder {folder.path}: {len(pending)} trials to run in {len(cells)} cells"
                      f" ({ablation.executor_name}, {workers} worker{'s' if workers > 1 else ''})")
        left = {cell: sum(1 for s in pending if (s.environment, s.arm, s.condition) == cell) for cell in cells}
        with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                      TimeRemainingColumn(), console=console) as progress:
            trials = progress.add_task("trials", total=len(pending))
            finished_cells = progress.add_task("cells", total=len(cells))

            def advance(result) -> None:
                cell = (result.spec.environment, result.spec.arm, result.spec.condition)
                left[cell] -= 1
                progress.update(trials, advance=1,
                                description=f"trials (last: {escape(result.spec.trial_id)} {result.outcome.value})")
                if left[cell] == 0:
                    progress.advance(finished_cells)

            return ablation.run(advance)
    finally:
        ablation.close()
