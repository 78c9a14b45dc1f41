"""What the report needs from the stored steps: refusals per validator rule and attacked steps per
attack kind, per trial; with ``metrics.release_readings``, also the rows the authors' release would
have written for ADR and TLR (:mod:`safeembodai_core.metrics.release`).

A refusal is an attempt that a rule judged invalid (for at least one of its signals); an
attacked step of kind K is a step with at least one :class:`~safeembodai_core.models.AttackRecord`
of kind K. Both are counted by the run's state store, :meth:`StateStore.step_facts
<safeembodai_core.contracts.components.StateStore.step_facts>`: a store may count them its own way (the
built-in ``sqlite`` store asks its tables, no step is parsed), any other counts the records
``StateStore.steps(trial_id)`` returns. The release's rows need every step record (its attempts,
verdicts and views): they are read through ``steps`` only when asked for.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable, Mapping

from ..contracts.components import StateStore, StepFacts
from ..metrics.release import ReleaseCounts, trial_counts
from ..models import Outcome


@dataclass
class TrialFacts(StepFacts):
    release: ReleaseCounts | None = None  # the release's ADR/TLR rows, when asked for


def from_store(store: StateStore, trial_ids: Iterable[str],
               release: Mapping[str, Outcome] | None = None) -> dict[str, TrialFacts]:
    """Facts of ``trial_ids`` as ``store`` counts them; ``release`` (trial id -> outcome) asks for
    the release's rows of those trials too."""
    ids = list(dict.fromkeys(trial_ids))
    counted = store.step_facts(ids)
    facts = {}
    for trial_id in ids:
        trial = counted.get(trial_id) or StepFacts()
        facts[trial_id] = TrialFacts(refusals=trial.refusals, attacked_by_kind=trial.attacked_by_kind)
        if release is not None and trial_id in release:
            facts[trial_id].release = trial_counts(store.steps(trial_id), release[trial_id])
    return facts
