"""The paper's published figures (shipped as data) and the comparison with a run's cells."""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

from ..metrics import CellMetrics

COMPARED = ("moer", "adr", "tlr", "steps", "tokens", "distance_mm")


@lru_cache(maxsize=1)
def paper_results() -> dict[str, Any]:
    """The values read off Figures 5-8 of the paper (``data/paper_results.json``)."""
    path = Path(__file__).resolve().parents[1] / "data" / "paper_results.json"
    return json.loads(path.read_text(encoding="utf-8"))


def paper_value(metric: str, environment: str, arm: str, condition: str) -> float | None:
    """The paper's value for a cell, or None when the paper has none (or the cell is not the paper's)."""
    table = paper_results()["metrics"].get(metric, {})
    return table.get(arm, {}).get(condition, {}).get(environment)


def comparison_rows(cells: list[CellMetrics]) -> list[dict[str, Any]]:
    """One row per (cell, metric) the paper reports: ours with its interval, the paper's, inside or not."""
    rows = []
    for m in cells:
        for metric in COMPARED:
            theirs = paper_value(metric, m.environment, m.arm, m.condition)
            ours = getattr(m, metric)
            if theirs is None or ours.value is None:
                continue
            inside = ours.low is not None and ours.low <= theirs <= ours.high
            rows.append({"environment": m.environment, "arm": m.arm, "condition": m.condition, "metric": metric,
                         "ours": ours.value, "low": ours.low, "high": ours.high, "paper": theirs, "inside": inside})
    return rows
