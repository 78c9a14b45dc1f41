"""The tables of a run's ``report.md`` (written by ``ablate``/``report``), for the run page.

Only the Markdown tables are read, each under the heading above it: a row is a line starting with
``|``, cells split on unescaped ``|``, the separator row dropped, code backticks removed, backslash
escapes undone (report.md escapes names from data: ``\\[`` is ``[``). The text is shown as text
(the page escapes it); nothing else of the Markdown is interpreted.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

_SPLIT = re.compile(r"(?<!\\)\|")
_CODE_MARK = re.compile(r"(?<!\\)`")
#: CommonMark's backslash escapes of ASCII punctuation (report.md escapes names from data so)
_ESCAPED = re.compile(r"\\([!-/:-@\[-`{-~])")
_SEPARATOR = re.compile(r"^\|?\s*:?-{3,}")
#: Larger reports are not read (a hostile or broken file must not stall the page).
MAX_BYTES = 2_000_000


@dataclass
class Table:
    heading: str
    header: list[str]
    rows: list[list[str]] = field(default_factory=list)


def _cells(line: str) -> list[str]:
    parts = _SPLIT.split(line.strip().strip("|"))
    return [_ESCAPED.sub(r"\1", _CODE_MARK.sub("", part.strip())) for part in parts]


def report_tables(path: Path) -> list[Table]:
    """The tables of the report at ``path`` (none when it is missing, unreadable, too large or not a
    regular file)."""
    from .files import read_run_file  # a regular file only: never a FIFO, a device or a symlink

    data = read_run_file(path, MAX_BYTES)
    if data is None:
        return []
    lines = data.decode("utf-8", errors="replace").splitlines()
    tables: list[Table] = []
    heading, current = "", None
    for line in lines:
        if line.startswith("#"):
            heading, current = line.lstrip("#").strip(), None
        elif line.startswith("|"):
            if _SEPARATOR.match(line):
                continue
            if current is None:
                current = Table(heading, _cells(line))
                tables.append(current)
            else:
                current.rows.append(_cells(line))
        else:
            current = None
    return tables
