"""What the report needs from the stored steps: refusals per validator rule and attacked steps per
attack kind, per trial; with ``metrics.release_readings``, also the rows the authors' release would
have written for ADR and TLR (:mod:`safeembodai_core.metrics.release`).

A refusal is an attempt that a rule judged invalid (for at least one of its signals); an
attacked step of kind K is a step with at least one :class:`~safeembodai_core.models.AttackRecord`
of kind K. Both come from the store's step records: for the built-in ``sqlite`` store by two
aggregate queries over its ``verdicts`` and ``attacks`` tables (milliseconds for thousands of
trials, no step is parsed), for any other store through ``StateStore.steps(trial_id)``. The
release's rows need every step record parsed (its attempts, verdicts and views): they are read
only when asked for.
"""

from __future__ import annotations

import sqlite3
from collections import Counter
from dataclasses import dataclass, field
from pathlib import Path
from typing import Iterable, Mapping

from ..components import StateStore
from ..logs import get_logger
from ..metrics.release import ReleaseCounts, trial_counts
from ..models import Outcome, StepRecord

log = get_logger(__name__)

_REFUSALS = ("SELECT trial_id, rule, COUNT(*) FROM (SELECT DISTINCT trial_id, step, attempt, rule FROM verdicts "
             "WHERE valid = 0) GROUP BY trial_id, rule")
_ATTACKS = ("SELECT trial_id, kind, COUNT(*) FROM (SELECT DISTINCT trial_id, step, kind FROM attacks) "
            "GROUP BY trial_id, kind")
_RECORDS = "SELECT trial_id, record FROM steps ORDER BY trial_id, step"


@dataclass
class TrialFacts:
    refusals: Counter = field(default_factory=Counter)  # rule -> attempts it refused
    attacked_by_kind: Counter = field(default_factory=Counter)  # kind -> steps attacked with it
    release: ReleaseCounts | None = None  # the release's ADR/TLR rows, when asked for


def _uri(path: Path, mode: str) -> str:
    """The database's URI for ``mode``; read-only leaves nothing behind in the run folder.

    A read-only connection to a WAL database creates ``-wal`` and ``-shm`` files and, unable to
    checkpoint, never removes them. Without a ``-wal`` file no writer has the database open (a
    writer's connection keeps one; the last writer to close removes it), so it is read
    ``immutable``: no lock, no journal, nothing created (as ``safeembodai show`` reads it). With
    one (a writer still open, or killed), ``mode=ro`` reads the log too, sharing the files there.
    """
    uri = f"{path.resolve().as_uri()}?mode={mode}"
    if mode == "ro" and not Path(f"{path}-wal").exists():
        uri += "&immutable=1"
    return uri


def from_sqlite(path: Path, trial_ids: Iterable[str],
                release: Mapping[str, Outcome] | None = None) -> dict[str, TrialFacts] | None:
    """Facts of ``trial_ids`` from a ``sqlite`` store's file; None if it cannot be read so.

    ``release`` (trial id -> outcome) asks for the release's rows of those trials too.
    """
    wanted = set(trial_ids)
    for mode in ("ro", "rw"):  # read-only first; a WAL file without its -shm may need rw to open
        facts = {trial_id: TrialFacts() for trial_id in wanted}
        try:
            db = sqlite3.connect(_uri(path, mode), uri=True, timeout=5.0)
            try:
                for query, attribute in ((_REFUSALS, "refusals"), (_ATTACKS, "attacked_by_kind")):
                    for trial_id, name, count in db.execute(query):
                        if trial_id in wanted:
                            getattr(facts[trial_id], attribute)[name] += count
                if release is not None:
                    records: dict[str, list[StepRecord]] = {}
                    for trial_id, text in db.execute(_RECORDS):
                        if trial_id in wanted and trial_id in release:
                            records.setdefault(trial_id, []).append(StepRecord.model_validate_json(text))
                    _add_release(facts, records, release)
            finally:
                db.close()
        except sqlite3.Error as error:
            log.info("report.steps_unreadable", path=str(path), mode=mode, error=str(error))
            continue
        return facts
    return None


def from_store(store: StateStore, trial_ids: Iterable[str],
               release: Mapping[str, Outcome] | None = None) -> dict[str, TrialFacts]:
    """Facts of ``trial_ids`` read step by step through the store's interface (``release`` as in :func:`from_sqlite`)."""
    facts = {}
    records: dict[str, list[StepRecord]] = {}
    for trial_id in trial_ids:
        trial = facts[trial_id] = TrialFacts()
        for record in store.steps(trial_id):
            refused = {(a.index, v.rule) for a in record.attempts for v in a.verdicts if not v.valid}
            trial.refusals.update(rule for _, rule in refused)
            trial.attacked_by_kind.update({a.kind for a in record.attacks})
            if release is not None and trial_id in release:
                records.setdefault(trial_id, []).append(record)
    if release is not None:
        _add_release(facts, records, release)
    return facts


def _add_release(facts: dict[str, TrialFacts], records: Mapping[str, list[StepRecord]],
                 outcomes: Mapping[str, Outcome]) -> None:
    for trial_id, trial in facts.items():
        if trial_id in outcomes:
            trial.release = trial_counts(records.get(trial_id, []), outcomes[trial_id])


def sqlite_file(folder: Path, state_use: str, options: dict) -> Path | None:
    """The database file of a run's ``sqlite`` store, when that is the store and the file exists."""
    if state_use != "sqlite":
        return None
    path = Path(options["path"]).expanduser() if options.get("path") else folder / "results.sqlite"
    return path if path.is_file() else None
