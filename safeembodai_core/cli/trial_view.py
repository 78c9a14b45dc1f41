"""Show and save one trial: a rich table of its steps and its files on disk.

Every text a record holds (the instruction an attacker may have shaped, the LLM's plan and
refusal reasons, execution details) is shown through :func:`~safeembodai_core.trust.text.terminal_markup`:
control characters visible, rich markup escaped, secrets masked.
"""

from __future__ import annotations

import json
from pathlib import Path

from rich.table import Table

from ..models import StepRecord, TrialResult
from ..trust.text import storable, terminal_markup


def step_table(steps: list[StepRecord]) -> Table:
    table = Table(title="steps", show_lines=True)
    for column in ("i", "instruction", "attempts", "plan / refusal", "executed"):
        table.add_column(column, overflow="fold")
    for record in steps:
        instruction = terminal_markup(record.instruction) + ("\n[red]attacked[/red]" if record.attacks else "")
        notes = []
        for attempt in record.attempts:
            if attempt.accepted and attempt.response is not None:
                flag = " [yellow](flagged attack)[/yellow]" if attempt.response.flags_attack else ""
                notes.append(f"ok: {terminal_markup(attempt.response.planning[:160])}{flag}")
            else:
                notes.append("refused: " + terminal_markup("; ".join(attempt.failures())[:200]))
        if record.enforced is not None:  # on_exhausted: enforce: what ran is the rules' cut, not an answer
            notes.append("enforced: " + terminal_markup(record.enforced.note[:300]))
        executed = "\n".join(
            terminal_markup(f"{item.signal.describe()} -> {item.result.detail or 'done'}") for item in record.executed
        ) or "-"
        if record.status == "executing":
            executed = "[red]results not recorded; planned:[/red] " + terminal_markup(
                ", ".join(signal.describe() for signal in record.planned))
        table.add_row(str(record.step), instruction, str(len(record.attempts)), "\n".join(notes), executed)
    return table


def save_trial(folder: Path, result: TrialResult, steps: list[StepRecord], picture: bytes | None) -> None:
    """Write ``trial.json``, ``steps.jsonl`` and (if the world drew one) ``trajectory.png``.

    Records go through :func:`~safeembodai_core.trust.text.storable` first, as into any store.
    """
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "trial.json").write_text(storable(result).model_dump_json(indent=2), encoding="utf-8")
    with (folder / "steps.jsonl").open("w", encoding="utf-8") as handle:
        for record in steps:
            handle.write(json.dumps(storable(record).model_dump(mode="json")) + "\n")
    if picture:
        (folder / "trajectory.png").write_bytes(picture)
