"""``safeembodai ablate SCENARIO``: every trial of every cell, in parallel, resumable, summarised.

Ctrl-C (SIGINT) and SIGTERM stop the run cleanly: workers are killed, finished trials stay
recorded, the resume command is printed and the exit code is 130 or 143 (128 + the signal).

``--resume RUN`` alone resumes the scenario the run folder recorded (``scenario.json``); given
with SCENARIO (and the same overrides) it checks that they match. ``--set``, ``--seed`` and
``--backend`` with ``--resume`` alone are refused: they would change a recorded scenario.
"""

from __future__ import annotations

import signal

import click

from .common import load, load_recorded, scenario_options


@click.command("ablate")
@scenario_options(required=False)
@click.option("--workers", type=click.IntRange(min=1), default=1, show_default=True,
              help="Worker processes (for trials that compute: the mock, many rooms).")
@click.option("--concurrency", type=click.IntRange(min=1, max=256), default=None,
              help="Trials in flight per worker, in threads (default: the backend's concurrency option, "
                   "8 for a remote litellm model, 1 otherwise).")
@click.option("--executor", type=click.Choice(["serial", "process", "ray"]), default=None,
              help="Where trials run (default: serial for 1 worker and --concurrency 1, process otherwise).")
@click.option("--address", default=None,
              help="With --executor ray: the cluster, HOST:PORT, ray://HOST:PORT (Ray Client) or auto (RAY_ADDRESS, "
                   "or a cluster started on this machine); default: a Ray of this machine only.")
@click.option("--connect-timeout", type=click.FloatRange(min=0, min_open=True), default=30.0, show_default=True,
              help="Seconds to wait for the Ray cluster at --address before giving up.")
@click.option("--out", "out_root", type=click.Path(file_okay=False), default="runs", show_default=True,
              help="Folder that receives the run folder <scenario>-<time>.")
@click.option("--resume", "resume_dir", type=click.Path(file_okay=False, exists=True), default=None,
              help="Finish the missing trials of this run folder, with the scenario it recorded "
                   "(SCENARIO, if given, must be the same, overrides included).")
@click.option("--no-report", is_flag=True, help="Skip report.md and figures at the end.")
@click.option("--cache", "cache_dir", type=click.Path(file_okay=False), default=None,
              help="Keep a paid model's replies in DIR/responses/, shared by runs (default: the run folder).")
@click.option("--no-cache", is_flag=True, help="Keep no replies: every call is made and paid.")
@click.option("--refresh", is_flag=True, help="Call again for every request, replacing kept replies.")
@click.option("--max-tokens", type=click.IntRange(min=1), default=None,
              help="Stop cleanly once the trials finished use this many tokens (resume to go on).")
@click.option("--max-cost", type=click.FloatRange(min=0, min_open=True), default=None,
              help="Stop cleanly once the trials finished cost this many US dollars at the model's list price.")
@click.option("--dry-run", is_flag=True,
              help="Estimate the calls, tokens and cost of the run (one step per environment and arm with the "
                   "offline mock) and exit; nothing is sent, no folder is made.")
@click.option("--bags", type=click.Choice(["mcap", "sqlite3"]), default=None,
              help="Also write each trial's ROS 2 bag into RUN/bags/ as it ends (docs/robots.md).")
@click.option("--rerun", "recordings", is_flag=True,
              help="Also write each trial's Rerun recording into RUN/recordings/ as it ends (the rerun extra; "
                   "docs/view.md).")
def ablate(scenario_path, backend, seed, overrides, workers, concurrency, executor, address, connect_timeout, out_root,
           resume_dir, no_report, cache_dir, no_cache, refresh, max_tokens, max_cost, dry_run, bags,
           recordings) -> None:
    """Run the ablation of SCENARIO: environments x arms x conditions x trials.

    With --resume RUN, SCENARIO may be left out: the run's recorded scenario is used.
    """
    from rich.console import Console
    from rich.markup import escape

    from ..ablation import Ablation
    from ..ablation.executors import WorkersLost
    from ..ablation.lifeline import StopSignals
    from ..ablation.plan import RunPlan
    from ..ablation.relay import RelayError
    from ..ablation.spending import SpendingCapReached
    from ..errors import SafeEmbodAIError
    from .summary import summary_table

    cache = _cache_settings(cache_dir, no_cache, refresh, resume_dir)
    if scenario_path is not None:
        scenario, plugins = load(scenario_path, backend, seed, overrides)
    elif resume_dir is None:
        raise click.UsageError("Missing argument 'SCENARIO' (or --resume RUN to finish a run).")
    elif backend is not None or seed is not None or overrides:
        raise click.UsageError("--set, --seed and --backend would change the scenario the run recorded; resume with "
                               "--resume RUN alone, or give them with the SCENARIO the run started with.")
    else:
        scenario, plugins = load_recorded(resume_dir)
    if dry_run:
        from .estimate_view import show_estimate

        show_estimate(scenario, plugins, resume_dir)
        return
    plan = RunPlan.prepare(scenario, plugins, workers=workers, concurrency=concurrency, executor=executor,
                           address=address, connect_timeout_s=connect_timeout, bags=bags, recordings=recordings,
                           cache=cache, max_tokens=max_tokens, max_cost=max_cost, warm_workers=True,
                           scenario_checked=True, resume=resume_dir)  # every check, before any folder is made
    console = Console(emoji=False)
    with StopSignals() as stop:
        ablation = Ablation.start(plan, out_root)
        folder = ablation.folder
        try:
            results, report = _run(console, ablation, report=not no_report)
            console.print(summary_table(scenario, results, plugins=plugins))
            if report is not None:
                console.print(f"report: {report}")
        except (KeyboardInterrupt, SafeEmbodAIError) as error:
            # a signal sent to the whole process group also kills workers: the broken pool is the signal's doing
            if isinstance(error, (WorkersLost, RelayError)) and stop.signum is None:
                raise SafeEmbodAIError(f"{error}; finished trials are recorded: resume with --resume {folder.path}") \
                    from None
            if isinstance(error, SpendingCapReached):
                raise SafeEmbodAIError(f"{error}; finished trials are recorded, the answers of those cut off are "
                                       f"kept: resume with --resume {folder.path} (a cap counts from zero on "
                                       "each invocation)") from None
            if isinstance(error, SafeEmbodAIError) and stop.signum is None:
                raise
            console.print(f"[yellow]interrupted[/yellow] ({signal.Signals(stop.exit_code - 128).name}): "
                          f"finished trials are recorded; resume with --resume {escape(str(folder.path))}",
                          soft_wrap=True)
            raise SystemExit(stop.exit_code) from None
    console.print(f"run folder: {escape(str(folder.path))}", soft_wrap=True)
    from ..ablation.error_kinds import all_errored

    failed = all_errored(results)
    if failed:
        raise SafeEmbodAIError(f"{failed} -- once fixed, resume with --resume {folder.path}")


def _cache_settings(cache_dir, no_cache, refresh, resume_dir):
    """The response cache the options ask for (a --cache folder made absolute: a resume from another
    folder finds it); a resume without cache options keeps the run's folder and reads its replies
    (a --refresh is for the invocation that asked for it, not for every resume after it)."""
    from dataclasses import replace
    from pathlib import Path

    from ..loop.response_cache import CacheSettings

    if no_cache and (cache_dir or refresh):
        raise click.UsageError("--no-cache keeps no replies: drop --cache and --refresh, or --no-cache")
    if resume_dir is not None and not (cache_dir or no_cache or refresh):
        return replace(CacheSettings.recorded(resume_dir), read=True)
    folder = str(Path(cache_dir).expanduser().resolve()) if cache_dir else None
    return CacheSettings(enabled=not no_cache, folder=folder, read=not refresh)


def _run(console, ablation, report=False):
    """Run the pending trials of ``ablation`` (closed at the end); return every result of the run and,
    with ``report``, the report written from the run's own store (its steps give refusals and attack
    kinds) before it closes."""
    from rich.markup import escape

    from ..trust.text import terminal_text
    from ..report.words import plural
    from .progress import AblationProgress

    plan, folder = ablation.plan, ablation.folder
    try:
        pending = ablation.pending()
        cells = {(s.environment, s.arm, s.condition) for s in pending}
        console.print(f"run folder: {escape(str(folder.path))}", soft_wrap=True)  # whole, to copy
        in_flight = f", {plan.concurrency} in flight per worker" if plan.concurrency > 1 else ""
        at = f" at {escape(terminal_text(plan.where))}" if plan.where else ""
        console.print(f"{plural(len(pending), 'trial')} to run in {plural(len(cells), 'cell')}"
                      f" ({ablation.executor_name}{at}, {plural(plan.workers, 'worker')}{in_flight})", soft_wrap=True)
        left = {cell: sum(1 for s in pending if (s.environment, s.arm, s.condition) == cell) for cell in cells}
        with AblationProgress(console) as progress:
            trials = progress.add_task("trials", total=len(pending))
            finished_cells = progress.add_task("cells", total=len(cells))

            def advance(result) -> None:
                cell = (result.spec.environment, result.spec.arm, result.spec.condition)
                left[cell] -= 1
                progress.last = f"last: {terminal_text(result.spec.trial_id)} {result.outcome.value}"
                progress.advance(trials)
                if left[cell] == 0:
                    progress.advance(finished_cells)

            results = ablation.run(advance)
        if not report:
            return results, None
        from ..report import write_report

        return results, write_report(folder.path, ablation.scenario, results, store=ablation.store,
                                     plugins=ablation.plugins)
    finally:
        ablation.close()
