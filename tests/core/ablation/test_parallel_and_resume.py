"""Parallel workers give the same trials as one process; a killed run resumes without loss or repeats."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.scenario import load_scenario

pytestmark = pytest.mark.slow


def comparable(results):
    return {r.spec.trial_id: r.model_dump(exclude={"wall_time_s"}) for r in results}


def run(scenario, plugins, folder, **kwargs):
    ablation = Ablation(scenario, plugins, folder, **kwargs)
    try:
        return ablation.run()
    finally:
        ablation.close()


def test_two_worker_processes_give_the_same_trials_as_one(repo, plugins, tmp_path):
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=2", "max_steps=4"], plugins.registry)
    serial = run(scenario, plugins, RunFolder(tmp_path / "serial"))
    parallel = run(scenario, plugins, RunFolder(tmp_path / "parallel"), workers=2)
    assert comparable(serial) == comparable(parallel)
    assert len(serial) == 8
    assert len(list((tmp_path / "parallel" / "trajectories").glob("*.png"))) == 8


def _store_results(path: Path):
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    if not path.exists():
        return []
    store = SqliteStateStore(path)
    try:
        return store.results()
    finally:
        store.close()


def test_killed_ablation_resumes_with_no_lost_or_repeated_trial(repo, tmp_path):
    scenario = str(repo / "scenarios" / "quickstart.yaml")
    args = [sys.executable, "-m", "safeembodai_core", "ablate", scenario, "--set", "trials=10", "--set", "max_steps=8",
            "--out", str(tmp_path), "--no-report"]
    process = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, start_new_session=True)
    deadline = time.monotonic() + 120
    folder = None
    while time.monotonic() < deadline:
        runs = list(tmp_path.glob("quickstart-*"))
        if runs and len(_store_results(runs[0] / "results.sqlite")) >= 2:
            folder = runs[0]
            break
        time.sleep(0.05)
    os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert folder is not None, "the ablation did not record 2 trials in time"
    before = {r.spec.trial_id: r for r in _store_results(folder / "results.sqlite")}
    assert 2 <= len(before) < 40, len(before)

    resumed = subprocess.run([*args[:-3], "--resume", str(folder)], capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    after = _store_results(folder / "results.sqlite")
    ids = [r.spec.trial_id for r in after]
    assert len(ids) == len(set(ids)) == 40
    by_id = {r.spec.trial_id: r for r in after}
    for trial_id, result in before.items():  # finished trials were not run again
        assert by_id[trial_id].wall_time_s == result.wall_time_s
    assert f"{40 - len(before)} trials to run" in resumed.stdout
    assert (folder / "report.md").exists()
