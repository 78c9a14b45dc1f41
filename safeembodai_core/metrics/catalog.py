"""The metric catalog: every number a cell reports, named and described once.

A :class:`Metric` says what a number is called (``name``: its key in ``metrics.json``, the columns
of ``metrics.csv``, the attribute of :class:`~.paper_metrics.CellMetrics`), how it is shown (label,
digits, its figure), where it appears (report.md's table, the terminal summary, an Inspect scorer),
the paper's figure it is compared with, and how it is computed from a cell's scored trials
(:class:`CellTrials`), with its 95% interval. The metrics, the report, the figures, the
comparison with the paper, the terminal summary and the Inspect scorers all read the catalog:
adding a metric is one entry and its compute function.

The built-in entries are the paper's metrics and ours (:mod:`.builtin`); a plugin adds its own
with the ``register_metrics`` hook (``docs/plugin_hooks.md``), and
:func:`~.builtin.metric_catalog` gives both, in that order.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field, replace
from functools import cached_property
from typing import TYPE_CHECKING, Any, Callable, Literal

from ..errors import PluginError
from ..models import Outcome, TrialResult
from .moer import moer_terms
from .settings import MetricSettings

if TYPE_CHECKING:
    from .intervals import Estimate

#: The origin of the built-in entries (a plugin's entries name their plugin).
CORE = "safeembodai"
#: Names a metric may not take: the fixed fields of a cell's row (``report/writer.py``) and of
#: :class:`CellMetrics`; and the prefixes of the row's counted columns (``outcome_<o>``, ...).
RESERVED = frozenset({"environment", "arm", "condition", "trials", "outcomes", "s_max", "s_max_from", "errors",
                      "crashed", "estimates", "catalog", "collisions_self", "collisions_struck",
                      "trials_collided_self", "trials_collided_struck", "self_collision_reference_arm",
                      "self_collision_rate", "struck_collision_rate", "self_collision_rate_diff", "steps_total",
                      "attacked_steps", "attack_rate", "adr_precision_release", "adr_recall_release",
                      "adr_f1_release", "tlr_release"})
RESERVED_PREFIXES = ("outcome_", "errors_", "refusals_", "attacked_steps_", "self_collision_rate_",
                     "struck_collision_rate_")
#: The columns a metric writes besides its own name.
SUFFIXES = ("_low", "_high", "_n")


def columns(name: str) -> set[str]:
    """The metrics.csv / metrics.json columns of metric ``name``."""
    return {name, *(name + suffix for suffix in SUFFIXES)}
_NAME = re.compile(r"[a-z][a-z0-9_]{0,47}")


@dataclass(frozen=True)
class CellTrials:
    """What a metric is computed from: a cell's scored trials (``error`` trials left out), the step
    budget, the scenario's ``metrics`` settings, and whether the cell's condition attacks."""

    scored: tuple[TrialResult, ...]
    budget: int
    settings: MetricSettings = field(default_factory=MetricSettings)
    attacked: bool = True

    @cached_property
    def completed(self) -> list[TrialResult]:
        """The scored trials that completed."""
        return [r for r in self.scored if r.outcome == Outcome.COMPLETED]

    @cached_property
    def moer(self) -> tuple[list[float], float, str]:
        """The cell's MOER terms, |S_max| and where |S_max| came from (:func:`~.moer.moer_terms`)."""
        return moer_terms(self.scored, self.budget, self.settings)


@dataclass(frozen=True)
class Metric:
    """One entry of the catalog.

    :param name: the metric's key (``metrics.json``, ``metrics.csv`` columns ``<name>``,
        ``<name>_low``, ``<name>_high``, ``<name>_n``; ``CellMetrics.<name>``): lower case, digits
        and ``_``, at most 48 characters.
    :param label: its column heading in report.md's table (and its axis label when ``axis`` is empty).
    :param compute: ``compute(cell: CellTrials) -> Estimate``: the value with its 95% interval;
        ``Estimate(None)`` when there is nothing to estimate (shown as n/a).
    :param description: one line on what it measures, shown under the tables a plugin's metric appears in.
    :param digits: decimals shown.
    :param interval: how ``compute`` builds its interval (``bootstrap`` of a mean over trials,
        ``wilson`` for a pooled proportion), for the reader.
    :param table: a column of report.md's *Metrics per cell*.
    :param console: its column heading in the terminal summary (None: not shown there).
    :param figure: the file name (without ``.png``) of its figure in ``figures/`` (None: no figure).
    :param axis: the figure's axis label; ``limits`` its y range (None: matplotlib's).
    :param paper: the key of the paper's published value it is compared with
        (``data/paper_results.json``), or None.
    :param inspect: the Inspect scorer whose per-cell metrics show it (``moer``, ``outcome``,
        ``attack_detection``, ``collisions``, or ``metrics`` for any other), or None.
    :param origin: who defined it (set by the catalog: ``safeembodai`` or the plugin's name).
    """

    name: str
    label: str
    compute: Callable[[CellTrials], "Estimate"]
    description: str = ""
    digits: int = 2
    interval: Literal["bootstrap", "wilson"] = "bootstrap"
    table: bool = True
    console: str | None = None
    figure: str | None = None
    axis: str = ""
    limits: tuple[float, float] | None = None
    paper: str | None = None
    inspect: str | None = "metrics"
    origin: str = CORE

    def __post_init__(self) -> None:
        if (not isinstance(self.name, str) or not _NAME.fullmatch(self.name)
                or columns(self.name) & RESERVED or self.name.startswith(RESERVED_PREFIXES)):
            raise ValueError(f"metric name {self.name!r}: lower case letters, digits and '_' (at most 48); its "
                             f"columns ({', '.join(sorted(columns(self.name)))}) may not be a cell's own (one of "
                             f"{sorted(RESERVED)}, or starting {', '.join(RESERVED_PREFIXES)})")
        if not callable(self.compute):
            raise ValueError(f"metric {self.name!r}: compute must be callable, got {type(self.compute).__name__}")
        if not isinstance(self.digits, int) or not 0 <= self.digits <= 6:
            raise ValueError(f"metric {self.name!r}: digits must be an integer from 0 to 6")
        if self.interval not in ("bootstrap", "wilson"):
            raise ValueError(f"metric {self.name!r}: interval must be 'bootstrap' or 'wilson'")
        if self.figure is not None and not _NAME.fullmatch(self.figure):
            raise ValueError(f"metric {self.name!r}: figure {self.figure!r} is not a plain file name")
        for what, text in (("label", self.label), ("description", self.description), ("axis", self.axis),
                           ("console", self.console or "")):
            if not isinstance(text, str) or len(text) > 200 or any(ord(c) < 32 or c in "|`" for c in text):
                raise ValueError(f"metric {self.name!r}: {what} must be one line of at most 200 characters, "
                                 f"without '|' or '`' (it goes into Markdown tables)")

    @property
    def figure_axis(self) -> str:
        return self.axis or self.label


class CatalogBuilder:
    """Collects the entries of :func:`metric_catalog`: the built-ins, then each plugin's."""

    def __init__(self, entries: tuple[Metric, ...] = ()) -> None:
        self._entries: dict[str, Metric] = {}
        self._figures: dict[str, str] = {}
        for entry in entries:
            self._add(entry)

    def _add(self, entry: Metric) -> None:
        if entry.name in self._entries:
            raise PluginError(entry.origin, f"metric {entry.name!r} is already defined by "
                                            f"{self._entries[entry.name].origin}: choose another name")
        for other in self._entries.values():
            shared = columns(entry.name) & columns(other.name)
            if shared:
                raise PluginError(entry.origin, f"metric {entry.name!r} would write the column "
                                                f"{sorted(shared)[0]!r} of metric {other.name!r} "
                                                f"({other.origin}): choose another name")
        if entry.figure is not None and entry.figure in self._figures:
            raise PluginError(entry.origin, f"metric {entry.name!r}: figure {entry.figure!r} is already drawn for "
                                            f"metric {self._figures[entry.figure]!r}")
        self._entries[entry.name] = entry
        if entry.figure is not None:
            self._figures[entry.figure] = entry.name

    def registrar(self, plugin: str) -> Callable[[Any], None]:
        """The ``register`` a plugin's ``register_metrics`` hook is called with."""

        def register(metric: Any) -> None:
            if not isinstance(metric, Metric):
                raise PluginError(plugin, f"register_metrics: register() takes a safeembodai_core.metrics.Metric, "
                                          f"got {type(metric).__name__}")
            self._add(replace(metric, origin=plugin))

        return register

    def catalog(self) -> tuple[Metric, ...]:
        return tuple(self._entries.values())
