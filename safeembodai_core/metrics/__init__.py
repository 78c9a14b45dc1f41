"""Metrics of an ablation: the paper's MOER, ADR, TLR and costs, with 95% intervals."""

from .intervals import Estimate, bootstrap_mean, newcombe, wilson
from .paper_metrics import CellMetrics, cell_metrics, group_by_cell, moer_term, moer_terms, s_max, settings_term
from .settings import ALPHA, BETA, DEFAULT_METRICS, MetricSettings

__all__ = ["ALPHA", "BETA", "DEFAULT_METRICS", "CellMetrics", "Estimate", "MetricSettings", "bootstrap_mean",
           "cell_metrics", "group_by_cell", "moer_term", "moer_terms", "newcombe", "s_max",
           "settings_term", "wilson"]
