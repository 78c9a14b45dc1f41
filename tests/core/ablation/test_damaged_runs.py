"""A run folder damaged under a run, or between runs, is an error naming the file, never a traceback,
a silent re-run or a report that says more than it has."""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from safeembodai_core.ablation import Ablation, AblationError, RunFolder
from safeembodai_core.ablation.error_kinds import crashed
from safeembodai_core.cli import main
from safeembodai_core.models import Outcome, TrialResult, TrialSpec
from safeembodai_core.runs.artefacts import TrialArtefacts
from safeembodai_core.scenario import load_scenario


def quickstart(repo, plugins, *overrides):
    return load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=2", "max_steps=2", *overrides],
                         plugins.registry)


def run(scenario, plugins, folder, resume=False, on_result=None):
    ablation = Ablation(scenario, plugins, folder, resume=resume)
    try:
        return ablation.run(on_result)
    finally:
        ablation.close()


def cli(capsys, *args) -> tuple[int, str]:
    with pytest.raises(SystemExit) as done:
        main(list(args))
    return done.value.code, capsys.readouterr().err


def one_line_error(stderr: str) -> str:
    lines = [line for line in stderr.splitlines() if line.startswith("Error: ")]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


def stored_ids(folder: Path) -> list[str]:
    with sqlite3.connect(folder / "results.sqlite") as db:
        return [row[0] for row in db.execute("SELECT trial_id FROM trials WHERE status = 'finished'")]


# -- 13: errors, not tracebacks ------------------------------------------------------------------


def test_a_full_disk_when_saving_a_picture_stops_the_run_with_the_file_named(repo, tmp_path, capsys, monkeypatch):
    real = Path.write_bytes
    written: list[Path] = []

    def write_bytes(self, data):
        if self.parent.name == "trajectories" and len(written) >= 3:
            raise OSError(28, "No space left on device")
        written.append(self)
        return real(self, data)

    monkeypatch.setattr(Path, "write_bytes", write_bytes)
    scenario = str(repo / "scenarios" / "quickstart.yaml")
    code, stderr = cli(capsys, "ablate", scenario, "--set", "trials=2", "--set", "max_steps=2", "--out", str(tmp_path),
                       "--no-report")
    line = one_line_error(stderr)
    assert code == 1 and "No space left on device" in line and "trajectories" in line and ".png" in line
    folder = next(tmp_path.glob("quickstart-*"))
    assert len(stored_ids(folder)) == 4  # the trial whose picture failed is recorded, not lost

    monkeypatch.setattr(Path, "write_bytes", real)
    code, stderr = cli(capsys, "ablate", scenario, "--set", "trials=2", "--set", "max_steps=2", "--resume", str(folder),
                       "--no-report")
    assert code == 0, stderr
    assert len(set(stored_ids(folder))) == len(stored_ids(folder)) == 8
    assert len(list((folder / "trajectories").glob("*.png"))) == 8  # the lost picture was drawn again


def test_trajectories_being_a_file_is_an_error_naming_it(repo, plugins, tmp_path, capsys):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    run(scenario, plugins, folder)
    shutil.rmtree(folder.path / "trajectories")
    (folder.path / "trajectories").write_text("not a folder")
    before = stored_ids(folder.path)
    code, stderr = cli(capsys, "ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=2",
                       "--set", "max_steps=2", "--resume", str(folder.path))
    assert code == 1 and f"{folder.path / 'trajectories'} is not a folder" in one_line_error(stderr)
    assert stored_ids(folder.path) == before


def test_a_run_folder_that_cannot_be_locked_is_an_error_naming_the_lock(repo, plugins, tmp_path, capsys, monkeypatch):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    run(scenario, plugins, folder)
    before = stored_ids(folder.path)
    real_open = os.open

    def read_only_folder(path, flags, *args, **kwargs):  # as root chmod cannot refuse, so the refusal is simulated
        if str(path).endswith(".lock") and flags & (os.O_RDWR | os.O_WRONLY):
            raise PermissionError(13, "Permission denied")
        return real_open(path, flags, *args, **kwargs)

    monkeypatch.setattr(os, "open", read_only_folder)
    code, stderr = cli(capsys, "ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=2",
                       "--set", "max_steps=2", "--resume", str(folder.path))
    line = one_line_error(stderr)
    assert code == 1 and f"cannot open the lock file {folder.path / '.coordinator.lock'}: Permission denied" in line
    monkeypatch.setattr(os, "open", real_open)
    assert stored_ids(folder.path) == before


@pytest.mark.parametrize("content, says", [
    ({"hello": "world"}, "is not a recorded scenario (expected the keys"),
    ([1, 2, 3], "is not a recorded scenario (expected the keys"),
    ({"fingerprint": "x", "scenario": {"name": "t", "trials": "many"}}, "is not a recorded scenario: trials:"),
])
def test_report_on_a_scenario_json_that_is_not_a_recorded_scenario(tmp_path, capsys, content, says):
    (tmp_path / "scenario.json").write_text(json.dumps(content))
    code, stderr = cli(capsys, "report", str(tmp_path))
    assert code == 1 and f"{tmp_path / 'scenario.json'} {says}" in one_line_error(stderr)


# -- 14: pictures ----------------------------------------------------------------------------------


def test_a_picture_lost_to_an_interruption_is_drawn_again_on_resume(repo, plugins, tmp_path, monkeypatch):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    real_save = TrialArtefacts.save_picture
    saved: list[str] = []

    def interrupted_after_the_result(self, environment, result):  # kill between result write and PNG save
        if len(saved) == 3:
            raise KeyboardInterrupt
        saved.append(result.spec.trial_id)
        return real_save(self, environment, result)

    monkeypatch.setattr(TrialArtefacts, "save_picture", interrupted_after_the_result)
    with pytest.raises(KeyboardInterrupt):
        run(scenario, plugins, folder)
    monkeypatch.setattr(TrialArtefacts, "save_picture", real_save)
    recorded = stored_ids(folder.path)
    assert len(recorded) == 4 and len(list((folder.path / "trajectories").glob("*.png"))) == 3

    results = run(scenario, plugins, folder, resume=True)
    pictures = {p.name for p in (folder.path / "trajectories").glob("*.png")}
    assert pictures == {r.spec.trial_id.replace("/", "__") + ".png" for r in results} and len(pictures) == 8
    assert not list((folder.path / "trajectories").glob(".*"))  # no half-written file left over


@pytest.mark.slow
def test_report_draws_missing_pictures_and_counts_truthfully_those_it_cannot(repo, plugins, tmp_path, capsys,
                                                                             monkeypatch):
    from safeembodai_plugins.environments.flatland.world import FlatlandWorld as Flatland

    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    run(scenario, plugins, folder)
    pictures = sorted((folder.path / "trajectories").glob("*.png"))
    for picture in pictures[:2]:
        picture.unlink()
    code, _ = cli(capsys, "report", str(folder.path))
    assert code in (0, None) and all(p.exists() for p in pictures)
    assert "8 pictures in `trajectories/` (one per trial)." in (folder.path / "report.md").read_text()

    pictures[0].unlink()
    monkeypatch.setattr(Flatland, "trajectory_png", lambda self, poses, outcome: None)
    code, _ = cli(capsys, "report", str(folder.path))
    text = (folder.path / "report.md").read_text()
    assert "one per trial" not in text
    assert "7 pictures in `trajectories/` for 8 trials: 1 trials have none" in text
    assert pictures[0].stem.replace("__", "/") in text


# -- 15: the store must not vanish or empty under the run ------------------------------------------


def test_a_store_deleted_mid_run_stops_the_run_and_resume_refuses_it(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    seen: list[TrialResult] = []

    def delete_after_two(result):
        seen.append(result)
        if len(seen) == 2:
            (folder.path / "results.sqlite").unlink()

    with pytest.raises(AblationError, match=r"results.sqlite vanished during the run"):
        run(scenario, plugins, folder, on_result=delete_after_two)
    for leftover in folder.path.glob("results.sqlite-*"):
        leftover.unlink()
    with pytest.raises(AblationError,
                       match=r"results.sqlite holds only 0 of the 2 finished trials recorded in .*finished.jsonl"):
        Ablation(scenario, plugins, folder, resume=True)


def test_a_store_replaced_mid_run_stops_the_run(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    store = folder.path / "results.sqlite"

    def replace(result):
        if not (tmp_path / "copy.sqlite").exists():
            shutil.copy(store, tmp_path / "copy.sqlite")
            os.replace(tmp_path / "copy.sqlite", store)

    with pytest.raises(AblationError, match="results.sqlite was replaced during the run"):
        run(scenario, plugins, folder, on_result=replace)


def test_a_store_emptied_mid_run_fails_the_run(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    seen: list[TrialResult] = []

    def empty_after_three(result):
        seen.append(result)
        if len(seen) == 3:
            with sqlite3.connect(folder.path / "results.sqlite") as db:
                db.execute("DELETE FROM trials")

    with pytest.raises(AblationError, match=r"results.sqlite now holds only \d+ of the \d+ finished trials"):
        run(scenario, plugins, folder, on_result=empty_after_three)


def test_resume_refuses_a_store_that_lost_its_records(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    run(scenario, plugins, folder)
    with sqlite3.connect(folder.path / "results.sqlite") as db:
        db.execute("DELETE FROM trials WHERE arm = 'baseline'")
    with pytest.raises(AblationError, match=r"holds only 4 of the 8 finished trials .*\(missing: flatland/baseline/"):
        Ablation(scenario, plugins, folder, resume=True)


def test_resume_adds_trials_finished_after_the_coordinator_died_to_the_ledger(repo, plugins, tmp_path):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    run(scenario, plugins, folder)
    ledger = folder.finished()
    folder.ledger_path.write_text("".join(json.dumps(t) + "\n" for t in ledger[:5]) + '"cut sho')  # a killed append
    resumed = Ablation(scenario, plugins, folder, resume=True)
    try:
        assert resumed.pending() == []
    finally:
        resumed.close()
    assert sorted(folder.finished()) == sorted(ledger)


# -- 17: report on a running run -------------------------------------------------------------------


@pytest.mark.slow
def test_report_refuses_a_run_in_progress(repo, plugins, tmp_path, capsys):
    scenario = quickstart(repo, plugins)
    folder = RunFolder(tmp_path / "run")
    run(scenario, plugins, folder)
    running = Ablation(scenario, plugins, folder, resume=True)
    try:
        code, stderr = cli(capsys, "report", str(folder.path))
    finally:
        running.close()
    assert code == 1 and "run in progress" in one_line_error(stderr)
    assert not (folder.path / "report.md").exists()
    assert cli(capsys, "report", str(folder.path))[0] in (0, None)


# -- crashes are not backend errors -----------------------------------------------------------------


def error_trial(index: int, detail: str) -> TrialResult:
    spec = TrialSpec(trial_id=f"OF/a/c/{index}", environment="OF", arm="a", condition="c", index=index, seed=index)
    return TrialResult(spec=spec, outcome=Outcome.ERROR, steps=0, detail=detail)


@pytest.mark.parametrize("detail, is_crash", [
    ("ZeroDivisionError: division by zero", True),
    ("numpy.linalg.LinAlgError: Singular matrix", True),
    ("error: Not connected to physics server", True),  # pybullet.error
    ("KeyError: 'x'", True),
    ("scripted backend: no answer left after 2", False),
    ("llm backend 'gpt-4o' (model gpt-4o) gave up after 3 tries: RateLimitError: slow down", False),
    ("MO: the environment was closed", False),
    ("flatland: room_mm=100 is too small for the robot", False),
    ("components could not be built: plugin 'x': boom", False),
    ("state store could not record the trial's result: disk is full", False),
])
def test_crashes_are_told_from_outages_by_their_detail(detail, is_crash):
    assert crashed(error_trial(0, detail)) is is_crash


@pytest.mark.slow
def test_summary_and_report_count_crashes_apart_from_backend_errors(tmp_path):
    from rich.console import Console

    from safeembodai_core.cli.summary import summary_table
    from safeembodai_core.report import write_report
    from safeembodai_core.scenario import parse_scenario

    scenario = parse_scenario("name: t\nmax_steps: 20\nenvironments: [OF]\n", "t.yaml")
    ok = TrialResult(spec=TrialSpec(trial_id="OF/a/c/9", environment="OF", arm="a", condition="c", index=9, seed=9),
                     outcome=Outcome.COMPLETED, steps=3)
    results = [ok, error_trial(0, "ZeroDivisionError: division by zero"),
               error_trial(1, "scripted backend: no answer left after 2"),
               error_trial(2, "scripted backend: no answer left after 2")]
    console = Console(width=80, record=True)
    console.print(summary_table(scenario, results))
    text = console.export_text()
    header = next(line for line in text.splitlines() if line.startswith("env"))
    row = next(line for line in text.splitlines() if line.startswith("OF"))
    assert header.split()[-2:] == ["err", "crash"] and row.split()[-2:] == ["2", "1"]
    assert max(len(line) for line in text.splitlines()) <= 80
    write_report(tmp_path, scenario, results)
    assert "| 2 (2 backend) | 1 |" in (tmp_path / "report.md").read_text()  # error (by kind), crashed
    row = json.loads((tmp_path / "metrics.json").read_text())["cells"][0]
    assert (row["errors"], row["crashed"]) == (2, 1)


def test_the_terminal_summary_has_no_crash_column_without_crashes(tmp_path):
    from rich.console import Console

    from safeembodai_core.cli.summary import summary_table
    from safeembodai_core.scenario import parse_scenario

    scenario = parse_scenario("name: t\nmax_steps: 20\nenvironments: [OF]\n", "t.yaml")
    console = Console(width=80, record=True)
    console.print(summary_table(scenario, [error_trial(0, "scripted backend: no answer left after 2")]))
    assert "crash" not in console.export_text()


def test_an_unreadable_subprocess_cli_error_has_no_traceback(repo, tmp_path):
    (tmp_path / "scenario.json").write_text('{"fingerprint": 1}')
    completed = subprocess.run([sys.executable, "-m", "safeembodai_core", "report", str(tmp_path)],
                               capture_output=True, text=True)
    assert completed.returncode == 1 and "is not a recorded scenario" in one_line_error(completed.stderr)
