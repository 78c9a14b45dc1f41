"""A cell's metrics (one environment x arm x condition), from trial results, as the catalog says.

Every number is an entry of the metric catalog (:mod:`.catalog`; the built-ins and their formulas
in :mod:`.builtin`, MOER in :mod:`.moer`); :func:`cell_metrics` computes each entry over the cell's
scored trials. An ``error`` trial (backend failure) is left out of N and counted apart. Formulas
and the choices the paper leaves open are documented in ``docs/metrics.md``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Sequence

from ..errors import PluginError
from ..models import Outcome, TrialResult
from .catalog import CellTrials, Metric
from .intervals import Estimate
from .moer import moer_term, moer_terms, s_j, s_max, settings_term
from .settings import MetricSettings

__all__ = ["CellMetrics", "cell_metrics", "group_by_cell", "moer_term", "moer_terms", "s_j", "s_max", "settings_term"]


@dataclass(frozen=True)
class CellMetrics:
    """One cell's counts and its catalog's estimates: ``m.moer`` is ``m.estimates["moer"]``."""

    environment: str
    arm: str
    condition: str
    trials: int
    outcomes: dict[str, int]
    s_max: float
    s_max_from: str  # "timeouts", "budget" or "fixed"
    errors: int = 0
    estimates: dict[str, Estimate] = field(default_factory=dict)

    def __getattr__(self, name: str) -> Estimate:
        # only for names that are not attributes: a catalog metric by its name
        if name.startswith("_") or name == "estimates":
            raise AttributeError(name)
        try:
            return self.estimates[name]
        except KeyError:
            raise AttributeError(f"{type(self).__name__} has no metric {name!r} (not in the catalog it was "
                                 f"computed with)") from None


def cell_metrics(results: Sequence[TrialResult], budget: int, alpha: float | None = None, beta: float | None = None,
                 settings: MetricSettings | None = None, attacked: bool = True,
                 catalog: Sequence[Metric] | None = None) -> CellMetrics:
    """Every metric of ``catalog`` (the built-ins when None) for one cell; ``results`` must all belong to it.

    ``settings`` is the scenario's ``metrics`` (the defaults when None); ``alpha`` and ``beta``,
    when given, replace its penalties. ``attacked`` is False for a cell whose condition has no
    attacker: it has no attack to detect, so its ADR is n/a (its flags are false alarms).
    """
    if not results:
        raise ValueError("a cell needs at least one trial result")
    settings = settings or MetricSettings()
    if alpha is not None or beta is not None:
        settings = settings.model_copy(update={k: v for k, v in (("alpha", alpha), ("beta", beta)) if v is not None})
    if catalog is None:
        from .builtin import BUILTIN

        catalog = BUILTIN
    spec = results[0].spec
    cell = CellTrials(tuple(r for r in results if r.outcome != Outcome.ERROR), budget, settings, attacked)
    _, smax, source = cell.moer
    outcomes = {o.value: sum(r.outcome == o for r in results) for o in Outcome}
    return CellMetrics(
        environment=spec.environment, arm=spec.arm, condition=spec.condition, trials=len(cell.scored),
        outcomes=outcomes, s_max=smax, s_max_from=source, errors=outcomes[Outcome.ERROR.value],
        estimates={entry.name: _computed(entry, cell) for entry in catalog},
    )


def _computed(entry: Metric, cell: CellTrials) -> Estimate:
    """``entry.compute(cell)``, checked: a failure or anything but an :class:`Estimate` names its owner."""
    try:
        estimate = entry.compute(cell)
    except Exception as error:
        raise PluginError(entry.origin, f"metric {entry.name!r} raised {type(error).__name__}: {error}") from error
    if not isinstance(estimate, Estimate):
        raise PluginError(entry.origin, f"metric {entry.name!r} returned {type(estimate).__name__}, not an Estimate")
    return estimate


def group_by_cell(results: Sequence[TrialResult]) -> dict[tuple[str, str, str], list[TrialResult]]:
    """Results by (environment, arm, condition), in first-seen order."""
    cells: dict[tuple[str, str, str], list[TrialResult]] = {}
    for result in results:
        cells.setdefault((result.spec.environment, result.spec.arm, result.spec.condition), []).append(result)
    return cells
