"""``safeembodai show RUN --trial N``: a trial's steps as a human reviews them.

For each step: the prompt summary (the human instruction as the LLM received it, the attacks
that shaped it, tokens), every attempt's answer (perception with attack flags, plan, control
signals with their justifications) and verdicts, then what was executed with what result.
Without ``--trial`` it lists the trials in the file, ids never cut (they are what ``--trial``
takes). ``--trial N`` names trial N of every cell: in a run of several cells it must be narrowed
with ``--env/--arm/--condition`` or given as a full id, and the error lists the candidates.

Stored text is printed literally (rich ``Text``, never markup) and through
:func:`~safeembodai_core.trust.text.terminal_text`: an escape sequence or NUL an answer held
is shown as ``\x1b`` / ``\x00``, never sent to the terminal.
"""

from __future__ import annotations

from pathlib import Path

from rich.console import Console, Group
from rich.measure import Measurement
from rich.panel import Panel
from rich.table import Table
from rich.text import Text

from safeembodai_core.errors import StateStoreError
from safeembodai_core.models import Attempt, StepRecord
from safeembodai_core.trust.text import terminal_text as shown
from safeembodai_core.report.words import plural, trial_ending

from .sqlite_db import SqliteStateStore
from .sqlite_file import DEFAULT_FILE


def open_run(run: str | Path) -> SqliteStateStore:
    """The store of ``run``: a ``.sqlite`` file, or a folder holding ``results.sqlite``."""
    path = Path(run)
    if path.is_dir():
        path = path / DEFAULT_FILE
        if not path.is_file():
            raise StateStoreError(f"{str(run)!r} has no {DEFAULT_FILE}; pass the database file itself")
    return SqliteStateStore(path, readonly=True)


def in_cell(row: dict, environment: str | None, arm: str | None, condition: str | None) -> bool:
    """Whether trial ``row`` belongs to the cell the filters (None: any) describe."""
    return ((environment is None or row["environment"] == environment) and (arm is None or row["arm"] == arm)
            and (condition is None or row["condition"] == condition))


def pick_trial(trials: list[dict], wanted: str, environment: str | None, arm: str | None,
               condition: str | None) -> str:
    """The one trial id matching ``wanted`` (an index or a full id) and the cell filters."""
    rows = [row for row in trials if in_cell(row, environment, arm, condition)]
    if wanted.lstrip("-").isdigit():
        matches = [row["trial_id"] for row in rows if row["index"] == int(wanted)]
    else:
        matches = [row["trial_id"] for row in rows if row["trial_id"] == wanted]
    if not matches:
        known = ", ".join(row["trial_id"] for row in rows[:8]) or "none"
        raise StateStoreError(f"no trial {wanted!r} in this run (with the filters given); trials: {known}"
                              + (" ..." if len(rows) > 8 else ""))
    if len(matches) > 1:
        listed = "".join(f"\n  {shown(trial_id)}" for trial_id in matches)
        raise StateStoreError(f"trial {wanted!r} exists in {len(matches)} cells; pass one of these full ids to "
                              f"--trial, or narrow it with --env/--arm/--condition:{listed}")
    return matches[0]


def trial_list(trials: list[dict]) -> Table:
    """The trials as a compact table; ids never wrap (:func:`print_uncut` keeps them whole)."""
    table = Table(title="trials", box=None, padding=(0, 2, 0, 0), pad_edge=False, header_style="bold underline")
    for column in ("trial id", "status", "outcome", "steps"):
        table.add_column(column, no_wrap=True, justify="right" if column == "steps" else "left")
    for row in trials:
        table.add_row(*(Text(shown(str(v))) for v in (row["trial_id"], row["status"], row["outcome"] or "-",
                                                       row["steps"])))
    return table


def print_uncut(console: Console, table: Table) -> None:
    """Print ``table`` whole: wider than the console, it is printed at its own width (the terminal
    wraps the lines) rather than squeezed, since squeezing would cut the ids."""
    natural = Measurement.get(console, console.options.update_width(10_000), table).maximum
    if natural > console.width:
        table.width = natural
    console.print(table, crop=False)


def reply_facts(attempt: Attempt) -> str:
    """What the reply said about itself, shown safely: finish reason, choices, where it came from."""
    reason = "not reported" if attempt.finish_reason is None else shown(attempt.finish_reason)
    facts = [f"finish reason {reason}"]
    if attempt.choices is not None:
        facts.append(f"{attempt.choices} choice{'' if attempt.choices == 1 else 's'}")
    if attempt.origin:
        facts.append(f"from {shown(attempt.origin)}")
    return ", ".join(facts)


def _attempt(attempt: Attempt) -> Text:
    text = Text()
    verdict = "accepted" if attempt.accepted else "refused"
    text.append(f"attempt {attempt.index + 1}: {verdict}", style="green" if attempt.accepted else "red")
    text.append(f"  ({attempt.usage.prompt_tokens}+{attempt.usage.completion_tokens} tokens)\n", style="dim")
    text.append(f"  reply: {reply_facts(attempt)}\n", style="dim")
    if attempt.reasoning:
        text.append(f"  reasoning: {shown(attempt.reasoning[:300])}{' ...' if len(attempt.reasoning) > 300 else ''}\n",
                    style="dim")
    if attempt.parse_error is not None:
        text.append(f"  unparseable answer: {shown(attempt.parse_error)}\n", style="red")
        text.append(f"  raw: {shown(attempt.raw_text[:300])}\n", style="dim")
    response = attempt.response
    if response is not None:
        for entry in response.perception:
            flag = " [ATTACK]" if entry.is_attack else ""
            text.append(f"  perceived {shown(entry.input)}{flag}: ", style="bold yellow" if entry.is_attack else "bold")
            text.append(f"{shown(entry.result)}\n")
        text.append("  plan: ", style="bold")
        text.append(f"{shown(response.planning)}\n")
        for index, signal in enumerate(response.control):
            text.append(f"  {index + 1}. {signal.describe()}", style="cyan")
            text.append(f" -- {shown(signal.justification)}\n" if signal.justification else "\n")
    for verdict_ in attempt.verdicts:
        if not verdict_.valid:
            text.append(f"  x {shown(verdict_.line())}\n", style="red")
    passed = sorted({v.rule for v in attempt.verdicts if v.valid} - {v.rule for v in attempt.verdicts if not v.valid})
    if passed:
        text.append(f"  passed: {shown(', '.join(passed))}\n", style="green")
    text.rstrip()
    return text


def step_panel(record: StepRecord) -> Panel:
    """One step as a panel: prompt summary, attempts, execution."""
    head = Text()
    head.append("instruction: ", style="bold")
    head.append(shown(record.instruction) + "\n")
    for attack in record.attacks:
        head.append(f"attack ({shown(attack.attacker)}, {attack.channel}, {shown(attack.kind)}): ", style="bold red")
        head.append(f"{shown(attack.payload)}\n")
    usage = record.usage
    head.append(f"{plural(len(record.attempts), 'attempt')}, {usage.prompt_tokens} prompt + "
                f"{usage.completion_tokens} completion tokens", style="dim")
    if record.truth.target_in_view:
        head.append("; target in view", style="dim")
    executed = Text()
    executed.append("executed: ", style="bold")
    if record.status == "executing":
        executed.append("results never recorded (the trial failed mid-step); any of the plan may have run:",
                        style="bold red")
        for signal in record.planned:
            executed.append(f"\n  {signal.describe()} -> ?", style="yellow")
    elif not record.executed:
        executed.append("nothing" + ("" if record.accepted else " (no acceptable answer)"))
    if record.enforced is not None:  # on_exhausted: enforce -- the rules' cut of a refused answer, not the LLM's
        executed.append(f"\n  on_exhausted enforce: {shown(record.enforced.note)}", style="magenta")
    for item in record.executed:
        result = item.result
        style = "bold red" if result.collided else ("yellow" if result.stopped else "")
        detail = shown(result.detail) if result.detail else ("done" if not result.stopped else "stopped")
        executed.append(f"\n  {item.signal.describe()} -> {detail}", style=style)
    parts = [head, *(_attempt(a) for a in record.attempts), executed]
    title = f"step {record.step}" + (" [red](attacked)[/red]" if record.attacks else "")
    return Panel(Group(*parts), title=title, title_align="left")


def pilot_banner(run: str | Path) -> str | None:
    """What ``show`` says of who answered: a simulated pilot's banner, or that it cannot be told (a bare
    ``.sqlite`` file, or a folder whose ``scenario.json`` cannot be read back); None for a real LLM."""
    from safeembodai_core.scenario.reading import recorded_scenario
    from safeembodai_core.errors import SafeEmbodAIError
    from safeembodai_core.scenario.describe import describe_backend

    if not Path(run).is_dir():
        return "who answered is not recorded in a bare results file: it may have been a simulated pilot, not an LLM"
    try:
        scenario, plugins = recorded_scenario(run)
        simulated = describe_backend(scenario, plugins).simulated
    except SafeEmbodAIError as error:
        return (f"who answered cannot be told ({shown(str(error))[:200]}): it may have been a simulated pilot, "
                "not an LLM")
    return shown(simulated.upper()) if simulated else None


def show_run(run: str, trial: str | None, *, environment: str | None = None, arm: str | None = None,
             condition: str | None = None, console: Console | None = None) -> None:
    """Print the trials of ``run``, or the steps of one trial of it."""
    console = console or Console(emoji=False)
    store = open_run(run)
    try:
        trials = store.trials()
        if trial is None:
            print_uncut(console, trial_list([row for row in trials if in_cell(row, environment, arm, condition)]))
            return
        trial_id = pick_trial(trials, trial, environment, arm, condition)
        seed = next(row["seed"] for row in trials if row["trial_id"] == trial_id)
        steps = store.steps(trial_id)
        result = store.result(trial_id)
    finally:
        store.close()
    console.print(Text.assemble((shown(trial_id), "bold"), f" (seed {seed})"))
    pilot = pilot_banner(run)
    if pilot:
        console.print(Text(pilot, style="bold red"))
    for record in steps:
        console.print(step_panel(record))
    if result is None:
        console.print("trial did not finish (no result stored)")
    else:
        ending = trial_ending(result, steps)
        line = Text("outcome: ")
        line.append(result.outcome.value, style="bold")
        line.append(f" after {plural(result.steps, 'step')}" + (f" ({shown(ending)})" if ending else "")
                    + f"; distance {result.distance_mm:.0f} mm, collisions {result.collisions}, "
                    f"interventions {result.interventions}, tokens {result.tokens}")
        console.print(line)


