"""Metrics of an ablation: the paper's MOER, ADR, TLR and costs, with 95% intervals."""

from .intervals import Estimate, bootstrap_mean, wilson
from .paper_metrics import ALPHA, BETA, CellMetrics, cell_metrics, group_by_cell, moer_term, s_max

__all__ = ["ALPHA", "BETA", "CellMetrics", "Estimate", "bootstrap_mean", "cell_metrics", "group_by_cell", "moer_term",
           "s_max", "wilson"]
