"""Metrics of an ablation: the paper's MOER, ADR, TLR and costs, with 95% intervals, from one catalog."""

from .builtin import metric_catalog
from .catalog import CellTrials, Metric
from .intervals import Estimate, bootstrap_mean, newcombe, wilson
from .moer import moer_term, moer_terms, s_max, settings_term
from .paper_metrics import CellMetrics, cell_metrics, group_by_cell
from .settings import ALPHA, BETA, DEFAULT_METRICS, MetricSettings

__all__ = ["ALPHA", "BETA", "DEFAULT_METRICS", "CellMetrics", "CellTrials", "Estimate", "Metric", "MetricSettings",
           "bootstrap_mean", "cell_metrics", "group_by_cell", "metric_catalog", "moer_term", "moer_terms", "newcombe",
           "s_max", "settings_term", "wilson"]
