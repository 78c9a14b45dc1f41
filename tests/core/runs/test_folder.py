"""Run folders are never shared by two runs at once; failed trials are retried; bad setups are refused."""

from __future__ import annotations

import subprocess
import sys
import textwrap
import types
from pathlib import Path

import pytest

from safeembodai_core import hookimpl
from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.errors import SafeEmbodAIError, ScenarioError
from safeembodai_core.models import Outcome
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.scenario import load_scenario, parse_scenario


def quickstart(repo, plugins, *overrides):
    return load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=2", *overrides],
                         plugins.registry)


def test_two_coordinators_cannot_share_a_run_folder(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins)
    first = Ablation(scenario, plugins, RunFolder(tmp_path / "run"))
    try:
        with pytest.raises(SafeEmbodAIError, match="another 'safeembodai ablate' is running"):
            Ablation(scenario, plugins, RunFolder(tmp_path / "run"), resume=True)
    finally:
        first.close()
    Ablation(scenario, plugins, RunFolder(tmp_path / "run"), resume=True).close()  # free once the first ended


@pytest.mark.slow
def test_resume_waits_for_orphaned_workers(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins)
    Ablation(scenario, plugins, RunFolder(tmp_path / "run")).close()
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys, time
        from safeembodai_core.runs.folder import hold_worker_lock
        hold_worker_lock({str(tmp_path / "run")!r}); print("held", flush=True); time.sleep(60)
    """)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(SafeEmbodAIError, match=f"still alive \\(pid {holder.pid}\\)"):
            Ablation(scenario, plugins, RunFolder(tmp_path / "run"), resume=True)
    finally:
        holder.kill()
        holder.wait()
    Ablation(scenario, plugins, RunFolder(tmp_path / "run"), resume=True).close()


def _lock_files(folder):
    return sorted(path.name for path in folder.iterdir() if path.name.endswith(".lock"))


@pytest.mark.parametrize("workers", [1, 2])
@pytest.mark.slow
def test_a_finished_run_folder_holds_no_lock_files(repo, plugins, tmp_path, workers):
    scenario = quickstart(repo, plugins)
    ablation = Ablation(scenario, plugins, RunFolder(tmp_path / "run"), workers=workers)
    try:
        assert len(ablation.run()) == 4
        assert ".coordinator.lock" in _lock_files(tmp_path / "run")  # held while the run is open
    finally:
        ablation.close()
    assert _lock_files(tmp_path / "run") == []
    Ablation(scenario, plugins, RunFolder(tmp_path / "run"), resume=True).close()  # a resume ending cleanly
    assert _lock_files(tmp_path / "run") == []


@pytest.mark.slow
def test_safeembodai_ablate_and_report_leave_no_lock_files(repo, cli_runner, tmp_path):
    from safeembodai_core.cli import cli

    done = cli_runner.invoke(cli, ["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=1",
                                   "--set", "max_steps=2", "--out", str(tmp_path), "--no-report"])
    assert done.exit_code == 0, done.output
    [run] = [path for path in tmp_path.iterdir() if path.is_dir()]
    assert _lock_files(run) == []
    assert cli_runner.invoke(cli, ["report", str(run)]).exit_code == 0
    assert _lock_files(run) == []


WAITING_WORKER = textwrap.dedent("""
    import sys
    from safeembodai_core.runs.folder import hold_worker_lock
    hold_worker_lock(sys.argv[1]); print("held", flush=True); sys.stdin.read()
""")


def _waits_on(path, pid):
    """Whether ``pid`` is blocked waiting for a lock on ``path`` (a ``->`` line of /proc/locks)."""
    import os

    info = os.stat(path)
    wanted = f"{os.major(info.st_dev):02x}:{os.minor(info.st_dev):02x}:{info.st_ino}"
    lines = Path("/proc/locks").read_text().splitlines()
    return any("->" in line and wanted in line.split() and str(pid) in line.split() for line in lines)


@pytest.mark.skipif(not Path("/proc/locks").exists(), reason="needs /proc/locks to see a blocked waiter")
@pytest.mark.slow
def test_a_worker_waiting_on_a_removed_lock_file_still_keeps_a_resume_out(tmp_path):
    """The holder removes the file while a worker waits on it: the worker must lock the file the
    path names afterwards, or a resume would start beside a live worker."""
    import time

    from safeembodai_core.runs.folder import WORKERS_LOCK, RunInProgress, RunLock, _flock, _remove_held, _unlock

    path = tmp_path / WORKERS_LOCK
    held = _flock(path, exclusive=True, wait=False)
    worker = subprocess.Popen([sys.executable, "-c", WAITING_WORKER, str(tmp_path)], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not _waits_on(path, worker.pid):
            assert worker.poll() is None and time.monotonic() < deadline, "the worker never waited on the lock"
            time.sleep(0.05)
        _remove_held(path, held)
        _unlock(held)
        assert worker.stdout.readline().strip() == "held"
        assert path.exists()  # the worker made the file anew and holds that one
        with pytest.raises(RunInProgress, match=f"still alive \\(pid {worker.pid}\\)"):
            RunLock(tmp_path, wait_s=0.3).acquire()
    finally:
        worker.kill()
        worker.wait()
        worker.stdin.close()
        worker.stdout.close()


def test_error_trials_are_run_again_on_resume(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins, "backend.options.then=fail", "max_steps=8")
    folder = RunFolder(tmp_path / "run")
    first = Ablation(scenario, plugins, folder)
    try:
        results = first.run()
    finally:
        first.close()
    errored = {r.spec.trial_id for r in results if r.outcome == Outcome.ERROR}
    assert errored  # the scripted backend runs out of answers: an outage
    again = Ablation(scenario, plugins, folder, resume=True)
    try:
        assert {s.trial_id for s in again.pending()} == errored
    finally:
        again.close()


def test_inline_plugins_are_refused_for_worker_processes(repo, tmp_path):
    inline = types.ModuleType("inline_helper")
    inline.before_trial = hookimpl(lambda spec: None)
    plugins = load_plugins([inline], environ={})
    scenario = quickstart(repo, plugins)
    with pytest.raises(SafeEmbodAIError, match="inline plugins \\(inline_helper\\) cannot reach worker processes"):
        Ablation(scenario, plugins, RunFolder(tmp_path / "run"), workers=2)
    assert not (tmp_path / "run").exists()  # refused before the run folder is made


def test_two_unlabelled_uses_of_one_attacker_or_validator_are_refused():
    text = textwrap.dedent("""
        name: t
        environments: [flatland]
        conditions:
          double: {attackers: [prompt_injection, {use: prompt_injection, options: {rate: 0.9}}]}
        arms:
          a: {safety_validation: true, validators: [lidar_clearance, lidar_clearance]}
    """)
    with pytest.raises(ScenarioError) as error:
        parse_scenario(text, "t.yaml")
    assert ("attacker labels must be unique" in str(error.value)
            and "validator labels must be unique" in str(error.value))
    labelled = text.replace("{use: prompt_injection, options",
                            "{use: prompt_injection, label: second, options").replace(
        "[lidar_clearance, lidar_clearance]", "[lidar_clearance]")
    assert ([r.key for r in parse_scenario(labelled, "t.yaml").conditions["double"].attackers]
            == ["prompt_injection", "second"])


@pytest.mark.slow
def test_an_unwritable_run_folder_is_a_clear_error(repo, tmp_path):
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("a file where the run folder should go")
    completed = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate",
                                str(repo / "scenarios" / "quickstart.yaml"), "--out", str(blocker / "runs")],
                               capture_output=True, text=True)
    assert completed.returncode == 1 and "Traceback" not in completed.stderr
    assert "cannot write the run folder" in completed.stderr and "not-a-folder" in completed.stderr


def test_a_full_disk_stops_the_run_cleanly_and_it_resumes(repo, plugins, tmp_path, monkeypatch):
    from safeembodai_core.errors import StateStoreError
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    scenario = quickstart(repo, plugins, "trials=2")
    folder = RunFolder(tmp_path / "run")
    real_record, real_end = SqliteStateStore.record_step, SqliteStateStore.end_trial
    ended: list[str] = []

    def end_trial(self, result):
        if len(ended) >= 3:
            raise StateStoreError(f"{self.path}: database or disk is full")
        ended.append(result.spec.trial_id)
        real_end(self, result)

    def record_step(self, record):
        if len(ended) >= 3:
            raise StateStoreError(f"{self.path}: database or disk is full")
        real_record(self, record)

    monkeypatch.setattr(SqliteStateStore, "end_trial", end_trial)
    monkeypatch.setattr(SqliteStateStore, "record_step", record_step)
    ablation = Ablation(scenario, plugins, folder)
    try:
        with pytest.raises(StateStoreError, match="disk is full"):
            ablation.run()
    finally:
        ablation.close()
    monkeypatch.setattr(SqliteStateStore, "end_trial", real_end)
    monkeypatch.setattr(SqliteStateStore, "record_step", real_record)
    resumed = Ablation(scenario, plugins, folder, resume=True)
    try:
        assert len(resumed.pending()) == 8 - 3
        results = resumed.run()
    finally:
        resumed.close()
    ids = [r.spec.trial_id for r in results]
    assert len(ids) == len(set(ids)) == 8 and set(ended) <= set(ids)
