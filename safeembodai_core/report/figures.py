"""Figures in the style of the paper's Figures 5-8: grouped bars per environment, one bar per arm,
one panel per condition, 95% intervals as error bars and the paper's values as white diamonds."""

from __future__ import annotations

from pathlib import Path

from ..metrics import CellMetrics
from .paper import paper_value

FIGURES = {
    "moer": ("MOER", (0, 1.05)),
    "adr": ("ADR", (0, 1.0)),
    "tlr": ("TLR", (0, 1.0)),
    "steps": ("Steps (completed)", None),
    "tokens": ("Tokens (completed)", None),
    "distance_mm": ("Distance mm (completed)", None),
}


def draw_figures(cells: list[CellMetrics], folder: Path) -> list[Path]:
    """Write one PNG per metric into ``folder``; return their paths."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    folder.mkdir(parents=True, exist_ok=True)
    environments = list(dict.fromkeys(m.environment for m in cells))
    arms = list(dict.fromkeys(m.arm for m in cells))
    conditions = list(dict.fromkeys(m.condition for m in cells))
    lookup = {(m.environment, m.arm, m.condition): m for m in cells}
    width = 0.8 / max(1, len(arms))
    paths = []
    for metric, (label, limits) in FIGURES.items():
        fig, axes = plt.subplots(1, len(conditions), figsize=(3.2 * len(conditions) + 1, 3.2), squeeze=False, sharey=True)
        for axis, condition in zip(axes[0], conditions):
            for a, arm in enumerate(arms):
                xs, values, lows, highs, paper_x, paper_y = [], [], [], [], [], []
                for e, environment in enumerate(environments):
                    m = lookup.get((environment, arm, condition))
                    estimate = getattr(m, metric) if m else None
                    x = e + (a - (len(arms) - 1) / 2) * width
                    if estimate is not None and estimate.value is not None:
                        xs.append(x)
                        values.append(estimate.value)
                        lows.append(estimate.value - (estimate.low if estimate.low is not None else estimate.value))
                        highs.append((estimate.high if estimate.high is not None else estimate.value) - estimate.value)
                    theirs = paper_value(metric, environment, arm, condition)
                    if theirs is not None:
                        paper_x.append(x)
                        paper_y.append(theirs)
                axis.bar(xs, values, width=width * 0.95, yerr=[lows, highs], capsize=2, label=arm, color=f"C{a}")
                if paper_x:
                    axis.scatter(paper_x, paper_y, marker="D", s=28, facecolors="white", edgecolors="black",
                                 linewidths=1.2, zorder=4, label="paper (GPT-4o)")
            axis.set_xticks(range(len(environments)), environments)
            axis.set_title(condition.replace("_", " "))
            if limits:
                axis.set_ylim(*limits)
        axes[0][0].set_ylabel(label)
        handles: dict[str, object] = {}
        for axis in axes[0]:
            for handle, name in zip(*axis.get_legend_handles_labels()):
                handles.setdefault(name, handle)
        fig.legend(handles.values(), handles.keys(), loc="lower center", ncol=len(handles), fontsize="small",
                   frameon=False)
        fig.tight_layout(rect=(0, 0.08, 1, 1))
        path = folder / f"{metric}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        paths.append(path)
    return paths
