"""The progress display of ``safeembodai ablate``, laid out for an 80-column terminal.

Two bars (trials, cells) with counts, elapsed time and ETA in fixed columns, and under them the
last finished trial on a line of its own: a long trial id never squeezes the bars or cuts the
times, and a line too long for the terminal is shortened at its end, never wrapped.
"""

from __future__ import annotations

from typing import Any, Iterable

from rich.console import RenderableType
from rich.progress import (BarColumn, MofNCompleteColumn, Progress, Task, TextColumn, TimeElapsedColumn,
                           TimeRemainingColumn)
from rich.table import Column
from rich.text import Text

#: The narrowest bar drawn (rich would otherwise squeeze it to make room for other columns).
MIN_BAR_WIDTH = 20


class AblationProgress(Progress):
    """Trials and cells, then ``last: <trial id> <outcome>`` below them."""

    last = ""  # set before Progress.__init__ renders once

    def __init__(self, console: Any) -> None:
        super().__init__(
            TextColumn("{task.description}", table_column=Column(no_wrap=True, min_width=6)),
            BarColumn(bar_width=None, table_column=Column(ratio=1, min_width=MIN_BAR_WIDTH, max_width=40)),
            MofNCompleteColumn(table_column=Column(no_wrap=True, justify="right")),
            TimeElapsedColumn(table_column=Column(no_wrap=True)),
            TimeRemainingColumn(table_column=Column(no_wrap=True)),
            console=console,
        )

    def get_renderables(self) -> Iterable[RenderableType]:
        yield self.make_tasks_table(self.tasks)
        if self.last:
            yield Text(self.last, no_wrap=True, overflow="ellipsis")

    def make_tasks_table(self, tasks: Iterable[Task]) -> Any:
        table = super().make_tasks_table(tasks)
        table.expand = False
        return table
