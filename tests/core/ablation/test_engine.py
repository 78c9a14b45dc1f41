"""The ablation engine: every trial of every cell, a recorded scenario, refused mismatched resumes."""

from __future__ import annotations

import json

import pytest

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.scenario import load_scenario


def quickstart(repo, plugins, *overrides):
    return load_scenario(repo / "scenarios" / "quickstart.yaml", overrides, plugins.registry)


def test_serial_ablation_runs_every_cell_and_records_the_scenario(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins, "trials=1", "max_steps=3")
    folder = RunFolder.create(tmp_path, scenario)
    ablation = Ablation(scenario, plugins, folder)
    try:
        results = ablation.run()
    finally:
        ablation.close()
    assert sorted(r.spec.trial_id for r in results) == sorted(s.trial_id for s in ablation.runner.specs())
    assert len(results) == 1 * 2 * 2
    recorded = json.loads((folder.path / "scenario.json").read_text())
    assert recorded["scenario"]["trials"] == 1 and len(recorded["fingerprint"]) == 64
    assert len(list((folder.path / "trajectories").glob("*.png"))) == 4


def test_resume_refuses_a_changed_scenario_naming_the_keys(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins, "trials=1", "max_steps=2")
    folder = RunFolder.create(tmp_path, scenario)
    Ablation(scenario, plugins, folder).close()
    changed = quickstart(repo, plugins, "trials=2", "max_steps=2", "arms.safeembodai.failure_threshold=1")
    with pytest.raises(SafeEmbodAIError, match=r"changed: .*arms.safeembodai.failure_threshold.*trials"):
        Ablation(changed, plugins, folder, resume=True)


def test_a_run_folder_is_never_reused_for_a_new_run(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins, "trials=1")
    folder = RunFolder(tmp_path / "run")
    Ablation(scenario, plugins, folder).close()
    with pytest.raises(SafeEmbodAIError, match="already holds a run; use --resume"):
        Ablation(scenario, plugins, folder)


def test_resume_needs_a_store_that_keeps_results(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins, "trials=1", "state=memory")
    folder = RunFolder(tmp_path / "run")
    Ablation(scenario, plugins, folder).close()
    with pytest.raises(SafeEmbodAIError, match="keeps no results across runs"):
        Ablation(scenario, plugins, folder, resume=True)
    with pytest.raises(SafeEmbodAIError, match="needs a persistent state store"):
        Ablation(quickstart(repo, plugins, "trials=1", "state=memory"), plugins, RunFolder(tmp_path / "r2"),
                 workers=2).run()
    assert not (tmp_path / "r2").exists()  # refused before the folder is made: nothing to resume


@pytest.mark.parametrize("options, message", [
    ({"workers": 3, "executor": "serial"}, "--executor serial runs one trial at a time, not --workers 3"),
    ({"address": "head:6379"}, "--address is the address of a Ray cluster"),
    ({"address": "head:6379", "executor": "process", "workers": 2}, "the process executor would ignore it"),
])
def test_options_the_executor_would_ignore_are_refused(repo, plugins, tmp_path, options, message):
    with pytest.raises(SafeEmbodAIError, match=message):
        Ablation(quickstart(repo, plugins, "trials=1"), plugins, RunFolder(tmp_path / "run"), **options)
    assert not (tmp_path / "run").exists()


def test_not_a_run_folder_is_named(tmp_path, repo, plugins):
    with pytest.raises(SafeEmbodAIError, match="is not a run folder"):
        Ablation(quickstart(repo, plugins), plugins, RunFolder(tmp_path), resume=True)
