"""``safeembodai export RUN``: a run's trials as ROS 2 bags (MCAP or SQLite), for Foxglove, RViz
and ``ros2 bag``, or as Rerun recordings (``--format rrd``: the room in 3D).

The run folder keeps answers, verdicts and commands but not sensor readings, so each trial is
replayed from its recorded answers (:mod:`safeembodai_core.loop.replay`, no LLM called) and must
agree with its record step by step; the bag is then written as a trial recorded with ``ablate
--bags`` writes it (:mod:`safeembodai_core.ros.bag_export`), the recording by
:mod:`safeembodai_core.runs.rerun_recording`.

A ``serve-robot`` session's run folder (its scenario's backend ``outside``) holds no answers: its
commands came over the wire. Its own bag, recorded as it went, is written again in the format asked
(:func:`~safeembodai_core.serve_robot.session_bag.export_session_bag`); a session served with ``--bag
none`` has nothing to export, and ``--format rrd`` is refused for a session (not made yet).
"""

from __future__ import annotations

import click

FORMATS = {"mcap": "mcap", "sqlite": "sqlite3", "sqlite3": "sqlite3", "rrd": "rrd"}


@click.command("export")
@click.argument("run_dir", metavar="RUN", type=click.Path(file_okay=False, exists=True))
@click.option("--trial", "trials", multiple=True, metavar="ID",
              help="Full trial id (environment/arm/condition/index); repeatable. Default: every trial with a result.")
@click.option("--format", "form", type=click.Choice(sorted(FORMATS)), default="mcap", show_default=True,
              help="rosbag2 storage: mcap (Foxglove opens the .mcap inside) or sqlite3; or rrd, a Rerun recording "
                   "(the rerun extra).")
@click.option("--out", "out", type=click.Path(), required=True,
              help="The bag folder or .rrd file (one --trial), or a folder to put one per trial in.")
def export(run_dir: str, trials: tuple[str, ...], form: str, out: str) -> None:
    """Write the trials of RUN as ROS 2 bags (scan, camera, pose, markers, commands and the LLM's words)
    or Rerun recordings (the same, in 3D)."""
    from pathlib import Path

    from rich.console import Console
    from rich.progress import Progress

    from ..errors import SafeEmbodAIError, StateStoreError
    from ..loop.replay import replay_trial
    from ..runs.rerun_recording import import_rerun, write_recording
    from ..ros.bag_export import write_bag
    from ..runs.files import trial_file_name
    from ..runs.runner import ScenarioRunner
    from ..serve_robot.session_bag import export_session_bag
    from ..serve_robot.session_record import is_session
    from ..trust.text import terminal_markup
    from .common import load_recorded

    scenario, plugins = load_recorded(run_dir)
    runner = ScenarioRunner(scenario, plugins, run_dir=run_dir)
    console = Console(stderr=True, emoji=False)
    def read(what: str, call):  # a corrupt row is an error naming the run and what could not be read
        try:
            return call()
        except StateStoreError as error:  # the store's own strict reading names the file, table and row
            raise SafeEmbodAIError(f"{run_dir}: cannot read {what}: {error}") from None
        except SafeEmbodAIError:
            raise
        except Exception as error:
            raise SafeEmbodAIError(f"{run_dir}: cannot read {what} from its state store: "
                                   f"{type(error).__name__}: {str(error).splitlines()[0]}") from None

    try:
        results = {r.spec.trial_id: r for r in read("the trials' results", runner.state.results)}
        specs = {spec.trial_id: spec for spec in runner.specs()}
        if trials:
            unknown = [t for t in trials if t not in specs]
            if unknown:
                raise SafeEmbodAIError(f"--trial {unknown[0]!r} is not a trial of {run_dir} "
                                       f"(ids look like {next(iter(specs))!r}; "
                                       f"'safeembodai show {run_dir}' lists them)")
            chosen = list(dict.fromkeys(trials))
        else:
            chosen = [t for t in specs if t in results]
            if not chosen:
                raise SafeEmbodAIError(f"{run_dir} has no finished trial to export")
        target = Path(out)
        if len(chosen) > 1 or not trials:
            if target.exists() and not target.is_dir():
                raise SafeEmbodAIError(f"--out {out} is a file: give a folder for several bags")
            suffix = ".rrd" if form == "rrd" else ""
            paths = {t: target / (trial_file_name(t) + suffix) for t in chosen}
        else:
            paths = {chosen[0]: target}
        for trial_id, path in paths.items():
            if path.exists():
                raise SafeEmbodAIError(f"{path} exists: choose a new --out (nothing is written over)")
        if is_session(scenario):
            if form == "rrd":
                raise SafeEmbodAIError(f"{run_dir} is a serve-robot session: --format rrd is not made for a session "
                                       "yet; export its bag (--format mcap, which Foxglove opens, or sqlite3)")
            for trial_id, path in paths.items():
                export_session_bag(run_dir, trial_id, path, FORMATS[form])
                console.print(f"{terminal_markup(trial_id)} -> {terminal_markup(str(path))}")
            return
        if form == "rrd":
            import_rerun()  # before any replay: a missing extra is said at once
        with Progress(console=console, transient=True) as progress:
            task = progress.add_task("replaying and writing " + ("recordings" if form == "rrd" else "bags"),
                                     total=len(paths))
            for trial_id, path in paths.items():
                spec = specs[trial_id]
                records = read(f"the steps of {trial_id}", lambda: runner.state.steps(trial_id))
                if not records:
                    raise SafeEmbodAIError(f"trial {trial_id} has no recorded step in {run_dir}")
                capture, replayed, _ = replay_trial(runner, spec, records)
                environment = runner.environment(spec.environment)
                if form == "rrd":
                    write_recording(path, spec, records, results.get(trial_id), capture, environment.robot)
                else:
                    messages = runner.artefacts.bag_messages(spec, capture, records, results.get(trial_id),
                                                             environment.robot)
                    write_bag(path, messages, FORMATS[form])
                progress.advance(task)
                console.print(f"{terminal_markup(trial_id)} -> {terminal_markup(str(path))}")
    finally:
        runner.close()
