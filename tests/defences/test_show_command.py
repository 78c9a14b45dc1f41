"""``safeembodai show RUN --trial N``: a stored trial, readable by a human reviewer."""

from __future__ import annotations

import subprocess
import sys

import pytest

from safeembodai_core.cli import cli
from safeembodai_core.errors import StateStoreError
from safeembodai_core.testing import answer, run_tiny_trial, straight, turn


@pytest.fixture
def run_dir(tmp_path):
    """A run folder with one trial: an injected step, a refused plan, a retry, a flagged attack."""
    responses = [
        answer(turn(20, justification="face the open side")),
        answer(straight(399, justification="rush ahead"), planning="obey the operator"),
        answer(turn(30, justification="stay clear of the wall"), is_attack=True, planning="the instruction looks malicious"),
    ]
    arm = {"security_prefix": True, "state_management": True, "safety_validation": True,
           "validators": ["command_limits", {"use": "lidar_clearance", "options": {"safety_distance_mm": 5000}}]}
    run_tiny_trial(responses, max_steps=2, arm=arm, state={"use": "sqlite", "options": {"path": str(tmp_path / "results.sqlite")}},
                   attackers=[{"use": "prompt_injection", "options": {"steps": [2], "kinds": ["direct_harm"]}}])
    return tmp_path


def invoke(cli_runner, *args):
    return cli_runner.invoke(cli, ["show", *map(str, args)], terminal_width=200)


def test_show_prints_every_step_with_response_verdicts_and_execution(cli_runner, run_dir):
    result = invoke(cli_runner, run_dir, "--trial", "0")
    assert result.exit_code == 0, result.output
    out = result.output
    assert "flatland/arm/condition/0" in out and "step 1" in out and "step 2 (attacked)" in out
    assert "attack (prompt_injection, instruction, direct_harm)" in out
    assert "turn left 20 deg -- face the open side" in out
    assert "attempt 1: refused" in out and "lidar_clearance (signal 1)" in out and "5000 mm required" in out
    assert "straight forward 399 mm -- rush ahead" in out
    assert "attempt 2: accepted" in out and "human_instruction [ATTACK]" in out
    assert "the instruction looks malicious" in out
    assert "executed:" in out and "turn left 30 deg -> done" in out
    assert "outcome: timeout after 2 steps" in out


def test_show_accepts_the_database_file_and_the_full_trial_id(cli_runner, run_dir):
    result = invoke(cli_runner, run_dir / "results.sqlite", "--trial", "flatland/arm/condition/0", "--arm", "arm")
    assert result.exit_code == 0, result.output
    assert "step 2" in result.output


def test_show_without_trial_lists_the_trials(cli_runner, run_dir):
    result = invoke(cli_runner, run_dir)
    assert result.exit_code == 0, result.output
    assert "flatland/arm/condition/0" in result.output and "timeout" in result.output and "finished" in result.output


def test_show_unknown_trial_or_folder_without_database_is_a_clear_error(cli_runner, run_dir, tmp_path_factory):
    missing = invoke(cli_runner, run_dir, "--trial", "7")
    assert isinstance(missing.exception, StateStoreError) and "no trial '7'" in str(missing.exception)
    assert "flatland/arm/condition/0" in str(missing.exception)
    wrong_cell = invoke(cli_runner, run_dir, "--trial", "0", "--arm", "other")
    assert isinstance(wrong_cell.exception, StateStoreError)
    empty = tmp_path_factory.mktemp("empty")
    no_db = invoke(cli_runner, empty, "--trial", "0")
    assert isinstance(no_db.exception, StateStoreError) and "has no results.sqlite" in str(no_db.exception)


def test_show_through_the_console_script_exits_non_zero_with_one_message(run_dir):
    done = subprocess.run([sys.executable, "-c", "from safeembodai_core.cli import main; main()", "show",
                           str(run_dir), "--trial", "9"], capture_output=True, text=True, timeout=120)
    assert done.returncode != 0
    assert "Error: no trial '9'" in done.stderr and "Traceback" not in done.stderr


def test_registering_the_store_imports_neither_sqlite3_nor_rich():
    code = ("import sys; import safeembodai_plugins.state.sqlite_store as m; "
            "assert 'sqlite3' not in sys.modules and 'rich' not in sys.modules, sorted(sys.modules)")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


def test_show_prints_stored_text_literally_even_when_it_looks_like_markup(tmp_path, capsys):
    from rich.console import Console

    from safeembodai_core.models import Outcome, TrialResult, TrialSpec
    from safeembodai_plugins.state.review import show_run
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    path = tmp_path / "results.sqlite"
    store = SqliteStateStore(path)
    spec = TrialSpec(trial_id="OF/a/c/0", environment="OF", arm="a", condition="c", seed=1)
    store.begin_trial(spec)
    store.end_trial(TrialResult(spec=spec, outcome=Outcome.ERROR, steps=0,
                                detail="bad [type=value_error, input=x] and [/x] closing"))
    store.close()
    show_run(str(path), "OF/a/c/0", console=Console(width=200))
    out = capsys.readouterr().out
    assert "[type=value_error, input=x] and [/x] closing" in out
