"""``safeembodai run SCENARIO``: one trial of one cell, printed step by step, saved to a folder."""

from __future__ import annotations

import time
from pathlib import Path

import click

from ..errors import ScenarioError
from ..report.words import plural, trial_ending
from .common import load, scenario_options


def _pick(kind: str, value: str | None, names: list[str]) -> str:
    if value is None:
        return names[0]
    if value not in names:
        raise ScenarioError(f"--{kind} {value!r} is not in the scenario; choose from {', '.join(names)}")
    return value


@click.command("run")
@scenario_options
@click.option("--env", "environment", default=None, help="Environment label (default: the scenario's first).")
@click.option("--arm", default=None, help="Arm (default: the scenario's first).")
@click.option("--condition", default=None, help="Condition (default: the scenario's first).")
@click.option("--trial", "index", type=click.IntRange(min=0), default=0, show_default=True,
              help="Trial index (picks the seed).")
@click.option("--out", "out_dir", type=click.Path(file_okay=False), default=None,
              help="Folder for trial.json, steps.jsonl and trajectory.png (default: runs/<scenario>-run-<time>).")
@click.option("--bag", type=click.Choice(["mcap", "sqlite3"]), default=None,
              help="Also write the trial's ROS 2 bag into the folder's bags/ (docs/robots.md).")
def run(scenario_path, backend, seed, overrides, environment, arm, condition, index, out_dir, bag) -> None:
    """Run one trial of SCENARIO and show what happened at every step."""
    from rich.console import Console

    from ..ablation.plan import RunPlan
    from ..scenario.describe import describe_backend
    from ..runs.runner import ScenarioRunner, trial_spec
    from ..trust.text import terminal_markup
    from .trial_view import save_trial, step_table

    scenario, plugins = load(scenario_path, backend, seed, overrides)
    env_label = _pick("env", environment, [e.key for e in scenario.environments])
    arm = _pick("arm", arm, list(scenario.arms))
    condition = _pick("condition", condition, list(scenario.conditions))
    RunPlan.prepare(scenario, plugins, scenario_checked=True)  # the plan's checks, before the folder is made
    folder = Path(out_dir or Path("runs") / f"{scenario.name}-run-{time.strftime('%Y%m%d-%H%M%S')}")
    if bag is not None:
        from ..runs.trial_files import record_artefacts

        record_artefacts(folder, bags=bag)
    runner = ScenarioRunner(scenario, plugins, run_dir=folder)
    spec = trial_spec(scenario, env_label, arm, condition, index)
    console = Console(stderr=False, emoji=False)  # LLM text: ":warning:" stays literal
    simulated = describe_backend(scenario, plugins).simulated  # every surface says a simulated pilot is one
    if simulated:
        console.print(f"[bold red]{terminal_markup(simulated.upper())}[/bold red]")
    try:
        with console.status(f"running {terminal_markup(spec.trial_id)} (seed {spec.seed})"):
            result = runner.run(spec)
        steps = runner.state.steps(spec.trial_id)
        picture = runner.artefacts.picture(runner.environment(env_label), result)  # captioned, as ablate's
        save_trial(folder, result, steps, picture)
    finally:
        runner.close()
    console.print(step_table(steps))
    ending = trial_ending(result, steps)
    console.print(f"[bold]{terminal_markup(spec.trial_id)}[/bold]: {result.outcome.value} after "
                  f"{plural(result.steps, 'step')}" + (f" ({terminal_markup(ending)})" if ending else "")
                  + f"; distance {result.distance_mm:.0f} mm, tokens {result.tokens}")
    if simulated:
        console.print(f"[bold red]{terminal_markup(simulated)}[/bold red]")
    console.print(f"saved to {terminal_markup(str(folder))}")
    if bag is not None:
        from ..runs.runner import bag_file

        console.print(f"bag: {terminal_markup(str(bag_file(folder, spec.trial_id)))}")
    if result.outcome.value == "error":  # a script must be able to tell: exit non-zero, everything saved
        from ..errors import SafeEmbodAIError

        raise SafeEmbodAIError(f"trial {spec.trial_id} ended in error ({result.error_kind or 'unknown'}): "
                               f"{result.detail or 'no detail'}; what it did is saved in {folder}")
