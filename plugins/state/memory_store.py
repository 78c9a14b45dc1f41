"""The ``memory`` state store's implementation (``memory.py`` registers it)."""

from __future__ import annotations

from collections.abc import Iterable

from safeembodai_core.contracts.components import StateStore, StepFacts
from safeembodai_core.models import ReferenceState, StepRecord, TrialResult, TrialSpec
from safeembodai_core.trust.text import storable


class MemoryStateStore(StateStore):
    """Step records, R_{i-1} and trial results in dictionaries of this process."""

    def __init__(self) -> None:
        self.specs: dict[str, TrialSpec] = {}
        self.records: dict[str, dict[int, StepRecord]] = {}
        self.results_by_id: dict[str, TrialResult] = {}

    def begin_trial(self, spec: TrialSpec) -> None:
        self.specs[spec.trial_id] = spec
        self.records[spec.trial_id] = {}
        self.results_by_id.pop(spec.trial_id, None)

    def record_step(self, record: StepRecord) -> None:
        self.records.setdefault(record.trial_id, {})[record.step] = storable(record).model_copy(deep=True)

    def reference_state(self, trial_id: str, step: int) -> ReferenceState | None:
        previous = self.records.get(trial_id, {}).get(step - 1)
        return previous.to_reference() if previous is not None else None

    def end_trial(self, result: TrialResult) -> None:
        self.results_by_id[result.spec.trial_id] = storable(result).model_copy(deep=True)

    def steps(self, trial_id: str) -> list[StepRecord]:
        records = self.records.get(trial_id, {})
        return [records[step].model_copy(deep=True) for step in sorted(records)]

    def step_facts(self, trial_ids: Iterable[str]) -> dict[str, StepFacts]:
        """Counted from the records kept, without copying them."""
        facts: dict[str, StepFacts] = {}
        for trial_id in trial_ids:
            facts[trial_id] = counted = StepFacts()
            for record in self.records.get(trial_id, {}).values():
                counted.add(record)
        return facts

    def results(self) -> list[TrialResult]:
        """The results of the trials finished in this process, in the order they ended."""
        return [r.model_copy(deep=True) for r in self.results_by_id.values()]
