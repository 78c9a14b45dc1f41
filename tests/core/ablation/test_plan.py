"""The run plan: one front door for a run. Every check runs once, before anything is written, and a
library user's ``Ablation`` is refused exactly where ``safeembodai ablate`` is."""

from __future__ import annotations

import pytest

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.ablation import plan as run_plan
from safeembodai_core.ablation.plan import AblationError, RunPlan
from safeembodai_core.scenario.reading import checked_scenario
from safeembodai_core.ablation.spending import SpendingCapReached
from safeembodai_core.cli import main
from safeembodai_core.errors import SafeEmbodAIError, ScenarioError
from safeembodai_core.plugin.manager import load_plugins
import safeembodai_core.runs.runner as runner_module
from safeembodai_core.runs.runner import PreflightError
from safeembodai_core.runs.trial_files import recording_file


@pytest.fixture
def quickstart(repo):
    return checked_scenario(repo / "scenarios" / "quickstart.yaml", load_plugins(), ["trials=1", "max_steps=3"])


@pytest.fixture
def counted(monkeypatch):
    """How many times the plan asked whether the store persists and ran the backend's preflight."""
    calls = {"store": 0, "preflight": 0}
    real_store, real_preflight = run_plan.store_is_persistent, runner_module.preflight

    def store(*args, **kwargs):
        calls["store"] += 1
        return real_store(*args, **kwargs)

    def preflight(*args, **kwargs):
        calls["preflight"] += 1
        return real_preflight(*args, **kwargs)

    monkeypatch.setattr(run_plan, "store_is_persistent", store)
    monkeypatch.setattr("safeembodai_core.runs.runner.preflight", preflight)
    return calls


def test_every_check_runs_once_and_the_opened_run_checks_nothing_again(quickstart, counted, tmp_path):
    scenario, plugins = quickstart
    plan = RunPlan.prepare(scenario, plugins, workers=2, scenario_checked=True)
    assert (plan.executor, plan.workers, plan.concurrency) == ("process", 2, 1)
    assert counted == {"store": 1, "preflight": 1}
    ablation = Ablation.start(plan, tmp_path / "runs")
    try:
        assert counted == {"store": 1, "preflight": 1} and ablation.executor_name == "process"
    finally:
        ablation.close()


def test_a_refused_plan_leaves_no_folder_and_the_library_is_refused_alike(quickstart, tmp_path):
    scenario, plugins = quickstart
    memory = scenario.model_copy(update={"state": scenario.state.model_copy(update={"use": "memory"})})
    with pytest.raises(AblationError, match="needs a persistent state store"):
        RunPlan.prepare(memory, plugins, workers=2)
    folder = RunFolder(tmp_path / "lib")
    with pytest.raises(AblationError, match="needs a persistent state store"):
        Ablation(memory, plugins, folder, workers=2)
    with pytest.raises(AblationError, match="--executor serial runs one trial at a time"):
        Ablation(scenario, plugins, folder, workers=2, executor="serial")
    assert not folder.path.exists()


def test_resuming_is_checked_by_the_plan_once_before_the_backend_or_the_folder_is_touched(quickstart, counted,
                                                                                             tmp_path, monkeypatch):
    scenario, plugins = quickstart
    ablation = Ablation.start(RunPlan.prepare(scenario, plugins, scenario_checked=True), tmp_path / "runs")
    folder = ablation.folder.path
    ablation.close()
    counted.update(store=0, preflight=0)
    plan = RunPlan.prepare(scenario, plugins, workers=2, scenario_checked=True, resume=folder)
    assert counted == {"store": 1, "preflight": 1}  # the persistent store asked once, for the resume and the workers
    Ablation.start(plan).close()
    assert counted == {"store": 1, "preflight": 1}

    other = scenario.model_copy(update={"max_steps": 2})
    with pytest.raises(SafeEmbodAIError, match="differs from the one .* was started with .*max_steps"):
        RunPlan.prepare(other, plugins, scenario_checked=True, resume=folder)
    memory = scenario.model_copy(update={"state": scenario.state.model_copy(update={"use": "memory"})})
    with pytest.raises(SafeEmbodAIError, match="differs"):  # the folder recorded sqlite: refused as another scenario
        RunPlan.prepare(memory, plugins, scenario_checked=True, resume=folder)
    assert not (folder / "trajectories").exists()  # no trial ran
    (folder / "trajectories").write_text("not a folder")
    before = sorted(p.name for p in folder.iterdir())
    with pytest.raises(AblationError, match="trajectories is not a folder"):
        RunPlan.prepare(scenario, plugins, scenario_checked=True, resume=folder)
    with pytest.raises(AblationError, match="trajectories is not a folder"):  # a library user's Ablation alike
        Ablation(scenario, plugins, RunFolder(folder), resume=True)
    assert counted["preflight"] == 1  # refused before the backend was asked anything
    assert sorted(p.name for p in folder.iterdir()) == before


def test_a_library_ablation_runs_the_backends_preflight(quickstart, tmp_path, monkeypatch):
    scenario, plugins = quickstart
    monkeypatch.setenv("SAFEEMBODAI_TEST_KEY", "sk-test-not-a-key")
    down = scenario.model_copy(update={"backend": scenario.backend.model_copy(update={
        "use": "gpt-4o", "options": {"api_base": "http://127.0.0.1:9", "api_key_env": "SAFEEMBODAI_TEST_KEY",
                                     "timeout_s": 2.0, "max_retries": 0}})})
    folder = RunFolder(tmp_path / "lib")
    with pytest.raises(PreflightError, match="nothing was run"):
        Ablation(down, plugins, folder)
    assert not folder.path.exists()


def test_a_spending_cap_stops_a_library_run_as_it_stops_the_cli(repo, tmp_path):
    scenario, plugins = checked_scenario(repo / "scenarios" / "quickstart.yaml", load_plugins(),
                                         ["trials=1", "max_steps=3", "backend=mock"])  # the mock counts tokens
    plan = RunPlan.prepare(scenario, plugins, max_tokens=1, scenario_checked=True)
    ablation = Ablation.start(plan, tmp_path / "runs")
    try:
        with pytest.raises(SpendingCapReached):
            ablation.run()
        assert len(ablation.recorded()) == 1  # the trial that crossed the cap is recorded; none after it
    finally:
        ablation.close()


def test_a_scenario_naming_a_missing_plugin_is_refused_by_every_way_in(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("name: bad\nenvironments: [flatland]\nbackend: {use: nowhere}\n"
                    "arms: {a: {}}\nconditions: {c: {}}\n")
    with pytest.raises(ScenarioError, match="nowhere"):
        checked_scenario(path)
    pytest.importorskip("gymnasium", reason="the gym extra: pip install -e '.[gym]'")
    from safeembodai_core.integrations.gym import scenarios as gym

    with pytest.raises(ScenarioError, match="nowhere"):
        gym.resolve(str(path), "flatland")


def test_ablate_rerun_writes_a_recording_per_trial_as_it_ends(repo, tmp_path, capsys):
    pytest.importorskip("rerun", reason="the rerun extra (pip install -e '.[rerun]') writes recordings")
    with pytest.raises(SystemExit) as done:
        main(["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=1", "--set", "max_steps=3",
              "--rerun", "--no-report", "--out", str(tmp_path / "runs")])
    assert done.value.code in (0, None), capsys.readouterr().err
    [run] = list((tmp_path / "runs").iterdir())
    scenario, _ = checked_scenario(repo / "scenarios" / "quickstart.yaml", overrides=["trials=1"])
    trials = [f"{e}/{a}/{c}/0" for e, a, c in scenario.cells()]
    for trial_id in trials:
        assert recording_file(run, trial_id).read_bytes().startswith(b"RRF2"), trial_id


def test_ablate_rerun_without_the_extra_fails_before_any_folder(repo, tmp_path, capsys, monkeypatch):
    from safeembodai_core.runs import rerun_recording as rerun_export
    from safeembodai_core.errors import SafeEmbodAIError

    def missing():
        raise SafeEmbodAIError("Rerun recordings need the rerun extra: pip install -e '.[rerun]'")

    monkeypatch.setattr(rerun_export, "import_rerun", missing)
    with pytest.raises(SystemExit) as done:
        main(["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=1", "--rerun",
              "--out", str(tmp_path / "runs")])
    assert done.value.code == 1 and "rerun extra" in capsys.readouterr().err
    assert not (tmp_path / "runs").exists()


def test_resuming_a_run_that_writes_recordings_needs_the_extra_before_anything_runs(repo, tmp_path, monkeypatch):
    from safeembodai_core.runs import rerun_recording as rerun_export
    from safeembodai_core.errors import SafeEmbodAIError
    from safeembodai_core.runs.trial_files import record_artefacts

    scenario, plugins = checked_scenario(repo / "scenarios" / "quickstart.yaml", load_plugins(), ["trials=1"])
    folder = RunFolder(tmp_path / "run")
    folder.start(scenario)
    record_artefacts(folder.path, recordings=True)  # the run was started with --rerun

    def missing():
        raise SafeEmbodAIError("Rerun recordings need the rerun extra")

    monkeypatch.setattr(rerun_export, "import_rerun", missing)
    with pytest.raises(SafeEmbodAIError, match="rerun extra"):
        RunPlan.prepare(scenario, plugins, resume=folder.path)
    with pytest.raises(SafeEmbodAIError, match="rerun extra"):
        Ablation(scenario, plugins, folder, resume=True)
    assert not (folder.path / "results.sqlite").exists()
