"""Show and save one trial: a rich table of its steps and its files on disk."""

from __future__ import annotations

import json
from pathlib import Path

from rich.markup import escape
from rich.table import Table

from ..models import StepRecord, TrialResult


def step_table(steps: list[StepRecord]) -> Table:
    table = Table(title="steps", show_lines=True)
    for column in ("i", "instruction", "attempts", "plan / refusal", "executed"):
        table.add_column(column, overflow="fold")
    for record in steps:
        instruction = escape(record.instruction) + ("\n[red]attacked[/red]" if record.attacks else "")
        notes = []
        for attempt in record.attempts:
            if attempt.accepted and attempt.response is not None:
                flag = " [yellow](flagged attack)[/yellow]" if attempt.response.flags_attack else ""
                notes.append(f"ok: {escape(attempt.response.planning[:160])}{flag}")
            else:
                notes.append("refused: " + escape("; ".join(attempt.failures())[:200]))
        executed = escape("\n".join(
            f"{item.signal.describe()} -> {item.result.detail or 'done'}" for item in record.executed
        )) or "-"
        table.add_row(str(record.step), instruction, str(len(record.attempts)), "\n".join(notes), executed)
    return table


def save_trial(folder: Path, result: TrialResult, steps: list[StepRecord], picture: bytes | None) -> None:
    """Write ``trial.json``, ``steps.jsonl`` and (if the world drew one) ``trajectory.png``."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "trial.json").write_text(result.model_dump_json(indent=2), encoding="utf-8")
    with (folder / "steps.jsonl").open("w", encoding="utf-8") as handle:
        for record in steps:
            handle.write(json.dumps(record.model_dump(mode="json")) + "\n")
    if picture:
        (folder / "trajectory.png").write_bytes(picture)
