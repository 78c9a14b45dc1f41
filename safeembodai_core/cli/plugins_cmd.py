"""``safeembodai plugins``: every plugin, where it came from, its hooks and its components."""

from __future__ import annotations

import json

import click


@click.command("plugins")
@click.option("--json", "as_json", is_flag=True, help="Print JSON instead of a table.")
def plugins(as_json: bool) -> None:
    """List plugins with their origin, hooks and registered components."""
    from rich.console import Console
    from rich.table import Table

    from ..plugins import load_plugins

    rows = load_plugins().describe()
    if as_json:
        click.echo(json.dumps(rows, indent=2))
        return
    table = Table(title="SafeEmbodAI plugins")
    for column in ("plugin", "source", "module / distribution", "components", "hooks"):
        table.add_column(column, overflow="fold")
    for row in rows:
        where = row["module"] + (f"\n{row['distribution']}" if row["distribution"] else "")
        table.add_row(row["name"], row["source"], where, "\n".join(row["components"]), "\n".join(row["hooks"]))
    Console().print(table)
