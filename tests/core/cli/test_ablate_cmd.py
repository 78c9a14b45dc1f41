"""``safeembodai ablate`` at the command line: resuming from the run folder alone, a missing
executor extra refused before any folder is made, a progress display that fits 80 columns."""

from __future__ import annotations

import subprocess
import sys

import pytest

from safeembodai_core.cli import cli


def _stored(folder) -> list:
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    store = SqliteStateStore(folder / "results.sqlite", readonly=True)
    try:
        return store.results()
    finally:
        store.close()


@pytest.fixture
def interrupted_run(repo, plugins, tmp_path):
    """A quickstart ablation (trials=3: 12 trials) stopped by Ctrl-C after its third trial."""
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.scenario import load_scenario

    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=3", "max_steps=4"], plugins.registry)
    folder = RunFolder.create(tmp_path / "runs", scenario)
    ablation = Ablation(scenario, plugins, folder)
    finished = []

    def stop_after_three(result) -> None:
        finished.append(result)
        if len(finished) == 3:
            raise KeyboardInterrupt

    try:
        with pytest.raises(KeyboardInterrupt):
            ablation.run(stop_after_three)
    finally:
        ablation.close()
    assert len(_stored(folder.path)) == 3
    return folder.path


def test_resume_needs_only_the_run_folder(cli_runner, interrupted_run):
    before = {r.spec.trial_id: r.wall_time_s for r in _stored(interrupted_run)}
    result = cli_runner.invoke(cli, ["ablate", "--resume", str(interrupted_run), "--no-report"])
    assert result.exit_code == 0, result.output
    assert "9 trials to run in 3 cells" in result.output  # the first cell is done
    after = {r.spec.trial_id: r.wall_time_s for r in _stored(interrupted_run)}
    assert len(after) == 12 and all(after[trial_id] == wall for trial_id, wall in before.items())


def test_resume_with_the_scenario_still_checks_that_it_matches(cli_runner, repo, interrupted_run):
    scenario = str(repo / "scenarios" / "quickstart.yaml")
    different = cli_runner.invoke(cli, ["ablate", scenario, "--set", "trials=3", "--resume", str(interrupted_run)])
    assert different.exit_code != 0 and "changed: max_steps" in str(different.exception)
    same = cli_runner.invoke(cli, ["ablate", scenario, "--set", "trials=3", "--set", "max_steps=4",
                                   "--resume", str(interrupted_run), "--no-report"])
    assert same.exit_code == 0, same.output


def test_overrides_with_resume_alone_are_refused(cli_runner, interrupted_run):
    for extra in (["--set", "trials=5"], ["--seed", "3"], ["--backend", "mock"]):
        result = cli_runner.invoke(cli, ["ablate", "--resume", str(interrupted_run), *extra])
        assert result.exit_code == 2, result.output
        assert "would change the scenario the run recorded" in result.output
    assert len(_stored(interrupted_run)) == 3


def test_ablate_without_scenario_or_resume_is_a_usage_error(cli_runner):
    result = cli_runner.invoke(cli, ["ablate"])
    assert result.exit_code == 2 and "Missing argument 'SCENARIO'" in result.output


def test_ray_executor_without_the_extra_makes_no_run_folder(repo, tmp_path):
    code = ("import sys; sys.modules['ray'] = None\n"
            "from safeembodai_core.cli import main\n"
            f"main(['ablate', {str(repo / 'scenarios' / 'quickstart.yaml')!r}, '--executor', 'ray', "
            f"'--out', {str(tmp_path / 'runs')!r}])\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 1, done.stderr
    assert 'the ray executor needs the ray extra: pip install -e ".[ray]"' in done.stderr
    assert not (tmp_path / "runs").exists() or not any((tmp_path / "runs").iterdir())


def test_the_progress_display_fits_80_columns(cli_runner, repo, tmp_path, monkeypatch):
    """The bars keep their width and the times stay whole; the last trial gets a line of its own."""
    import re

    from safeembodai_core.cli.progress import MIN_BAR_WIDTH

    long_label = ["--set", "conditions={no_attack: {}, a_rather_long_condition_name_for_an_attack: {}}"]
    monkeypatch.chdir(tmp_path)  # a short run folder path: "runs/quickstart-<time>"
    result = cli_runner.invoke(cli, ["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=2",
                                     "--set", "max_steps=2", *long_label, "--out", "runs", "--no-report"],
                               env={"COLUMNS": "80"})
    assert result.exit_code == 0, result.output
    lines = result.output.splitlines()
    assert max(map(len, lines)) <= 80, "\n".join(line for line in lines if len(line) > 80)
    assert "8 trials to run in 4 cells (serial, 1 worker)" in lines
    for name, count in (("trials", "8/8"), ("cells", "4/4")):
        row = next(line for line in lines if line.startswith(name + " "))
        assert len(re.findall("[━╸╺]", row)) >= MIN_BAR_WIDTH, row
        assert re.search(rf" {count} \d+:\d\d:\d\d \d+:\d\d:\d\d$", row), row
    assert any(re.fullmatch(r"last: flatland/\w+/\w+/1 \w+", line) for line in lines), lines


@pytest.mark.parametrize("options, message", [
    (["--executor", "serial", "--workers", "4"], "--executor serial runs one trial at a time, not --workers 4"),
    (["--address", "1.2.3.4:6379"], "--address is the address of a Ray cluster: use it with --executor ray"),
    (["--workers", "2", "--address", "1.2.3.4:6379"], "use it with --executor ray (the process executor"),
    (["--executor", "serial", "--workers", "4", "--address", "1.2.3.4:6379"], "not --workers 4"),
])
def test_options_the_executor_would_ignore_are_refused_before_any_folder(cli_runner, repo, tmp_path, options,
                                                                          message):
    result = cli_runner.invoke(cli, ["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=1",
                                     "--out", str(tmp_path / "runs"), *options])
    assert result.exit_code == 1, result.output
    assert message in str(result.exception) and "\n" not in str(result.exception)
    assert "to run in" not in result.output  # nothing ran
    assert not (tmp_path / "runs").exists()


def test_workers_with_a_store_that_keeps_nothing_make_no_run_folder(cli_runner, repo, tmp_path):
    result = cli_runner.invoke(cli, ["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=1",
                                     "--set", "state.use=memory", "--workers", "2", "--out", str(tmp_path / "runs")])
    assert result.exit_code == 1, result.output
    assert "needs a persistent state store (e.g. sqlite); the scenario uses 'memory'" in str(result.exception)
    assert not (tmp_path / "runs").exists()


def test_a_finished_run_folder_holds_only_its_database_file(cli_runner, repo, tmp_path):
    """The report reads the closed database without leaving -wal/-shm behind; ``show`` still reads it."""
    result = cli_runner.invoke(cli, ["ablate", str(repo / "scenarios" / "quickstart.yaml"), "--set", "trials=1",
                                     "--out", str(tmp_path / "runs")])
    assert result.exit_code == 0, result.output
    (folder,) = (tmp_path / "runs").iterdir()
    report = (folder / "report.md").read_text(encoding="utf-8")
    assert "did not leave for the report to read" not in report  # the steps were read, from the file
    assert sorted(p.name for p in folder.glob("results.sqlite*")) == ["results.sqlite"]
    shown = cli_runner.invoke(cli, ["show", str(folder)])
    assert shown.exit_code == 0, shown.output
    assert "flatland/safeembodai/attack/0" in shown.output and "finished" in shown.output
    assert sorted(p.name for p in folder.glob("results.sqlite*")) == ["results.sqlite"]
