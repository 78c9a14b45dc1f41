"""The paper's published figures (shipped as data) and the comparison with a run's cells.

Each of our metrics is compared with the paper's under the paper's definition: TLR is the paper's
lost steps over all steps (our ``tlr_all``; the authors' release counts actions judged after acting,
``metrics.release_readings``), never our ``tlr_after_seen``, which the paper does not report
(``docs/metrics.md``).
"""

from __future__ import annotations

import json
from functools import lru_cache
from pathlib import Path
from typing import Any

from typing import Sequence

from ..metrics import CellMetrics, Metric, metric_catalog


def compared(catalog: Sequence[Metric] | None = None) -> dict[str, str]:
    """Our metric -> the paper's metric (the key in ``data/paper_results.json``) it is compared with,
    as the catalog (the built-ins when None) says."""
    return {entry.name: entry.paper for entry in (catalog or metric_catalog()) if entry.paper}

_ROUNDING = 1e-9  # 1 - 6/20 is 0.7000000000000001: a value on the bound is inside


@lru_cache(maxsize=1)
def paper_results() -> dict[str, Any]:
    """The values read off Figures 5-8 of the paper (``data/paper_results.json``)."""
    path = Path(__file__).resolve().parents[1] / "data" / "paper_results.json"
    return json.loads(path.read_text(encoding="utf-8"))


def paper_value(metric: str, environment: str, arm: str, condition: str) -> float | None:
    """The paper's value of its ``metric`` for a cell, or None when the paper has none (or the cell
    is not the paper's)."""
    table = paper_results()["metrics"].get(metric, {})
    return table.get(arm, {}).get(condition, {}).get(environment)


def comparison_rows(cells: list[CellMetrics], catalog: Sequence[Metric] | None = None) -> list[dict[str, Any]]:
    """One row per (cell, metric) the paper reports: ours with its interval, the paper's, inside or not.

    ``metric`` is the paper's name, ``ours_metric`` the attribute of :class:`CellMetrics` compared.
    """
    rows = []
    for m in cells:
        for ours_metric, metric in compared(catalog).items():
            theirs = paper_value(metric, m.environment, m.arm, m.condition)
            ours = m.estimates.get(ours_metric)
            if theirs is None or ours is None or ours.value is None:
                continue
            inside = (None if ours.low is None or ours.high is None
                      else ours.low - _ROUNDING <= theirs <= ours.high + _ROUNDING)
            rows.append({"environment": m.environment, "arm": m.arm, "condition": m.condition, "metric": metric,
                         "ours_metric": ours_metric, "ours": ours.value, "low": ours.low, "high": ours.high,
                         "n": ours.n, "paper": theirs, "inside": inside})
    return rows
