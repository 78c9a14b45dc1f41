"""A run folder holding one live trial (``safeembodai_core.runs.live_trial``): what a session writes is a run
folder every reader of runs finds, its one trial finished once its result is in."""

from __future__ import annotations

import pytest

from safeembodai_core.models import Outcome, Pose, StepRecord, TrialResult
from safeembodai_core.runs.folder import RunFolder
from safeembodai_core.runs.live_trial import LiveTrial
from safeembodai_core.scenario.reading import checked_scenario, recorded_scenario
from safeembodai_core.serve_robot.session_record import session_scenario


@pytest.fixture
def session(repo, plugins):
    scenario, _ = checked_scenario(repo / "scenarios" / "quickstart.yaml", plugins, ["state={use: sqlite}"])
    label = scenario.environments[0].key
    return session_scenario(scenario, label), label


def test_a_live_trial_is_a_run_folders_one_finished_trial(tmp_path, session, plugins):
    scenario, label = session
    trial = LiveTrial(RunFolder(tmp_path / "session"), scenario, label=label, arm="live", condition="rosbridge",
                      seed=7)
    store = trial.begin(plugins)
    try:
        trial.record_step(StepRecord(trial_id=trial.spec.trial_id, step=1, instruction="drive", accepted=True,
                                     pose_before=Pose(x_mm=0, y_mm=0, heading_deg=0)))
        assert not trial.folder.finished()  # steps alone finish nothing
        trial.end(TrialResult(spec=trial.spec, outcome=Outcome.TIMEOUT, steps=1, detail="ended"))
        assert [s.step for s in store.steps(trial.spec.trial_id)] == [1]
    finally:
        trial.close()
    assert trial.spec.trial_id == f"{label}/live/rosbridge/0" and trial.spec.seed == 7
    assert trial.folder.finished() == [trial.spec.trial_id]
    recorded, _ = recorded_scenario(tmp_path / "session", plugins)  # read back as every reader of runs reads it
    assert recorded.name == scenario.name and list(recorded.arms) == ["live"]


def test_a_live_trial_needs_its_store_begun(tmp_path, session):
    scenario, label = session
    trial = LiveTrial(RunFolder(tmp_path / "session"), scenario, label=label, arm="live", condition="rosbridge")
    with pytest.raises(RuntimeError, match="begin"):
        trial.record_step(StepRecord(trial_id=trial.spec.trial_id, step=1, instruction="drive"))
    trial.close()  # nothing opened: nothing to close
