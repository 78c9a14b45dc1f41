"""Figures in the style of the paper's Figures 5-8: grouped bars per environment, one bar per arm,
one panel per condition, 95% intervals as error bars and the paper's values as white diamonds.

A diamond is drawn only where the metric has the paper's definition (``tlr.png`` plots our
``tlr_all``, the paper's TLR; ``tlr_after_seen.png`` is ours alone). A bar whose mean has fewer
than three trials behind it has no error bar and is labelled ``n=1`` or ``n=2``. ``note`` (the
banner of a simulated pilot) is printed on every figure.

The legend is built from the arms' colours, not from what a panel drew (a panel without bars, such
as ADR without attacks, has nothing to take a colour from); its title says what the bars are
(``bars``: backend and model, or a simulated pilot, and N per cell) and the diamonds' entry that
they are the paper's GPT-4o values.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Sequence

from ..metrics import CellMetrics, Metric, metric_catalog
from ..metrics.intervals import MIN_N_FOR_INTERVAL
from ..trust.text import terminal_text
from .paper import paper_value

if TYPE_CHECKING:
    from matplotlib.figure import Figure



def figures(catalog: Sequence[Metric] | None = None) -> dict[str, Metric]:
    """File name (without ``.png``) -> the metric drawn in it: every entry of ``catalog`` (the
    built-ins when None) that asks for a figure, in catalog order."""
    return {entry.figure: entry for entry in (catalog or metric_catalog()) if entry.figure}


#: The legend's word on the diamonds.
PAPER_LABEL = "paper: GPT-4o in EyeSim (diamonds)"


def draw_figures(cells: list[CellMetrics], folder: Path, catalog: Sequence[Metric] | None = None,
                 note: str | None = None, bars: str | None = None) -> list[Path]:
    """Write one PNG per metric of ``catalog`` with a figure (:func:`figures`) into ``folder``; return their paths.

    ``note`` is printed above every figure (a simulated pilot's banner); ``bars`` titles the legend
    (what the bars are: :meth:`~safeembodai_core.report.run_info.RunInfo.bars`).
    """
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, entry in figures(catalog).items():
        fig = metric_figure(cells, entry, note=note, bars=bars)
        path = folder / f"{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths


def metric_figure(cells: list[CellMetrics], metric: Metric | str, note: str | None = None,
                  bars: str | None = None) -> "Figure":
    """The figure of one metric (an entry, or a built-in's figure name such as ``tlr``): a pyplot
    figure, close it when done."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    entry = figures()[metric] if isinstance(metric, str) else metric
    label, limits, theirs_metric = entry.figure_axis, entry.limits, entry.paper
    environments = list(dict.fromkeys(m.environment for m in cells))
    arms = list(dict.fromkeys(m.arm for m in cells))
    conditions = list(dict.fromkeys(m.condition for m in cells))
    lookup = {(m.environment, m.arm, m.condition): m for m in cells}
    width = 0.8 / max(1, len(arms))
    fig, axes = plt.subplots(1, len(conditions), figsize=(3.2 * len(conditions) + 1, 3.9), squeeze=False, sharey=True)
    paper_drawn = False
    for axis, condition in zip(axes[0], conditions):
        drawn = 0
        for a, arm in enumerate(arms):
            xs, values, lows, highs, paper_x, paper_y, few = [], [], [], [], [], [], []
            for e, environment in enumerate(environments):
                m = lookup.get((environment, arm, condition))
                estimate = m.estimates.get(entry.name) if m else None
                x = e + (a - (len(arms) - 1) / 2) * width
                if estimate is not None and estimate.value is not None:
                    xs.append(x)
                    values.append(estimate.value)
                    if estimate.low is not None and estimate.high is not None:
                        lows.append(estimate.value - estimate.low)
                        highs.append(estimate.high - estimate.value)
                    else:  # nan: no error bar
                        lows.append(math.nan)
                        highs.append(math.nan)
                    if estimate.n < MIN_N_FOR_INTERVAL:
                        few.append((x, estimate.value, estimate.n))
                theirs = paper_value(theirs_metric, environment, arm, condition) if theirs_metric else None
                if theirs is not None:
                    paper_x.append(x)
                    paper_y.append(theirs)
            drawn += len(xs)
            axis.bar(xs, values, width=width * 0.95, yerr=[lows, highs], capsize=2, color=_colour(a))
            for x, value, n in few:
                axis.annotate(f"n={n}", (x, value), ha="center", va="bottom", fontsize="x-small",
                              xytext=(0, 2), textcoords="offset points")
            if paper_x:
                paper_drawn = True
                axis.scatter(paper_x, paper_y, marker="D", s=28, facecolors="white", edgecolors="black",
                             linewidths=1.2, zorder=4)
        axis.set_xticks(range(len(environments)), [_shown(e) for e in environments])
        axis.set_xlim(-0.5, len(environments) - 0.5)  # an empty panel spans the environments as the others do
        axis.set_title(_shown(condition).replace("_", " "))
        if not drawn:  # say why a panel is empty (ADR without attacks), rather than leave it blank
            axis.text(0.5, 0.5, "n/a: nothing to estimate", transform=axis.transAxes, ha="center", va="center",
                      fontsize="small", color="grey")
        if limits:
            axis.set_ylim(*limits)
    axes[0][0].set_ylabel(label)
    _legend(fig, arms, paper_drawn, bars)
    top = 1.0
    if note:
        fig.suptitle(_shown(note), fontsize="small", color="darkred", fontstyle="italic")
        top = 0.93
    fig.tight_layout(rect=(0, 0.17 if bars else 0.1, 1, top))
    return fig


def _shown(text: str) -> str:
    """A name from the store as a figure label: control characters shown as escapes (matplotlib
    warns about a glyph it lacks, printing the raw character to the terminal) and ``$`` kept from
    starting mathtext."""
    return terminal_text(text).replace("$", r"\$")


def _colour(index: int) -> str:
    return f"C{index}"


def _legend(fig: "Figure", arms: list[str], paper_drawn: bool, bars: str | None) -> None:
    """One entry per arm in its bars' colour, the diamonds when drawn, titled with what the bars are."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list = [Patch(facecolor=_colour(a), label=_shown(arm)) for a, arm in enumerate(arms)]
    if paper_drawn:
        handles.append(Line2D([], [], marker="D", linestyle="none", markersize=6, markerfacecolor="white",
                              markeredgecolor="black", markeredgewidth=1.2, label=PAPER_LABEL))
    fig.legend(handles=handles, loc="lower center", ncol=len(handles), fontsize="small", frameon=False,
               title=_shown(bars) if bars else None, title_fontsize="small")
