"""``safeembodai plugins``: every plugin, where it came from, its hooks and its components.

Three shapes, each keeping identifiers whole so that they can be searched and copied:

* at a terminal, one block per plugin (name, source, module, then its components and hooks),
  never wrapped inside an identifier;
* piped or redirected, a header row ``kind name plugin source module`` then one tab-separated
  line per component in those columns (``-`` for kind and name on the line of a plugin that
  registers no component), so that ``safeembodai plugins | grep lidar_clearance`` finds exactly
  one line;
* ``--json``, a list of plugins (``docs/plugins.md`` gives its shape).
"""

from __future__ import annotations

import json
import sys
from typing import Any

import click

#: The columns of the piped listing, printed as its first row.
PLAIN_COLUMNS = ("kind", "name", "plugin", "source", "module")


def plain_lines(rows: list[dict[str, Any]]) -> list[str]:
    """The header row (:data:`PLAIN_COLUMNS`), then one ``kind<TAB>name<TAB>plugin<TAB>source<TAB>module``
    line per component."""
    lines = ["\t".join(PLAIN_COLUMNS)]
    for row in rows:
        components = [tuple(component.split(":", 1)) for component in row["components"]] or [("-", "-")]
        for kind, name in components:
            lines.append("\t".join((kind, name, row["name"], row["source"], row["module"])))
    return lines


def packed(items: list[str], width: int, first: str, indent: str) -> list[str]:
    """``first`` and ``items`` joined by ", " into lines of at most ``width`` characters, breaking only
    between items (an item too long for any line gets one of its own); later lines start with ``indent``."""
    lines: list[str] = []
    for item in items:
        if not lines:
            lines.append(first + item)
        elif len(lines[-1]) + len(", ") + len(item) < width:
            lines[-1] += ", " + item
        else:
            lines[-1] += ","
            lines.append(indent + item)
    return lines


def render(rows: list[dict[str, Any]], console: Any) -> None:
    """The terminal listing: a block per plugin, a line per component, hooks packed between names."""
    from rich.text import Text

    def line(text: Text | str) -> None:
        console.print(text, overflow="ignore", crop=False, no_wrap=True)

    line(Text(f"SafeEmbodAI plugins ({len(rows)})", style="bold"))
    for row in rows:
        head = Text.assemble((row["name"], "bold"), "  ", (row["source"], "cyan"), "  ", row["module"])
        line(head)
        if row["distribution"]:
            line(Text(f"  from {row['distribution']}", style="dim"))
        for component in row["components"]:
            line(f"  {component}")
        for text in packed(row["hooks"], console.width, first="  hooks: ", indent="         "):
            line(Text(text, style="dim"))


@click.command("plugins")
@click.option("--json", "as_json", is_flag=True,
              help="Print JSON: a list of {name, source, module, distribution, hooks, components}.")
def plugins(as_json: bool) -> None:
    """List plugins with their origin, hooks and registered components.

    Piped, it prints a header row, then one tab-separated line per component: kind, name, plugin,
    source, module.
    """
    from ..plugin.manager import load_plugins

    rows = load_plugins().describe()
    if as_json:
        click.echo(json.dumps(rows, indent=2))
    elif not sys.stdout.isatty():
        for line in plain_lines(rows):
            click.echo(line)
    else:
        from rich.console import Console

        render(rows, Console())
