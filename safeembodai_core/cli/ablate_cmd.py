"""``safeembodai ablate SCENARIO``: every trial of every cell, in parallel, resumable, summarised."""

from __future__ import annotations


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
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn, TimeRemainingColumn

    from ..ablation import Ablation, RunFolder
    from .summary import summary_table

    scenario, plugins = load(scenario_path, backend, seed, overrides)
    folder = RunFolder(resume_dir) if resume_dir else RunFolder.create(out_root, scenario)
    console = Console()
    ablation = Ablation(scenario, plugins, folder, resume=resume_dir is not None, workers=workers,
                        executor=executor, address=address)
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

            try:
                results = ablation.run(advance)
            except KeyboardInterrupt:
                console.print(f"[yellow]interrupted[/yellow]: finished trials are recorded; "
                              f"resume with --resume {folder.path}")
                raise SystemExit(130) from None
    finally:
        ablation.close()
    console.print(summary_table(scenario, results))
    if not no_report:
        from ..report import write_report

        report = write_report(folder.path, scenario, results)
        console.print(f"report: {report}")
    console.print(f"run folder: {folder.path}")
