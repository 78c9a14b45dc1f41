"""A run folder holding one trial recorded as it happens: serve-robot's session and guard-mcp's.

The folder is started with the session's scenario (so ``show``, ``report`` and ``view`` find its one cell),
the trial's spec is ``<label>/<arm>/<condition>/0``, the scenario's state store is built as a run's is
(:class:`~safeembodai_core.plugin.building.ComponentBuilder`, in the folder) and the trial begun. The owner
records steps as they come, ends the trial once with its result (the store, then the folder's ledger) and
closes the store.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ..models import StepRecord, TrialResult, TrialSpec
from ..plugin.building import ComponentBuilder
from .folder import RunFolder

if TYPE_CHECKING:
    from ..contracts.components import StateStore
    from ..plugin.manager import Plugins
    from ..scenario import Scenario


class LiveTrial:
    """The one trial of ``folder`` (started here with ``scenario``); :meth:`begin` opens its store."""

    def __init__(self, folder: RunFolder, scenario: Scenario, *, label: str, arm: str, condition: str,
                 seed: int = 0) -> None:
        self.folder, self.scenario = folder, scenario
        self.spec = TrialSpec(trial_id=f"{label}/{arm}/{condition}/0", scenario=scenario.name, environment=label,
                              arm=arm, condition=condition, index=0, seed=seed)
        folder.start(scenario)
        self._store: StateStore | None = None

    def begin(self, plugins: Plugins) -> StateStore:
        """Build the scenario's state store in the folder and begin the trial in it."""
        store = ComponentBuilder(self.scenario, plugins, run_dir=self.folder.path).state_store()
        try:
            store.begin_trial(self.spec)
        except BaseException:
            store.close()
            raise
        self._store = store
        return store

    @property
    def store(self) -> StateStore:
        if self._store is None:
            raise RuntimeError("LiveTrial.begin() opens the store")
        return self._store

    def record_step(self, record: StepRecord) -> None:
        self.store.record_step(record)

    def end(self, result: TrialResult) -> None:
        """The trial's result: in the store, then in the folder's ledger of finished trials."""
        self.store.end_trial(result)
        self.folder.note_finished([self.spec.trial_id])

    def close(self) -> None:
        if self._store is not None:
            self._store.close()
