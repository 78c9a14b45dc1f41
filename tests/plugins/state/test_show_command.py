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
        answer(turn(30, justification="stay clear of the wall"), is_attack=True,
               planning="the instruction looks malicious"),
    ]
    arm = {"security_prefix": True, "state_management": True, "safety_validation": True,
           "validators": ["command_limits", {"use": "lidar_clearance", "options": {"safety_distance_mm": 5000}}]}
    run_tiny_trial(responses, max_steps=2, arm=arm,
                   state={"use": "sqlite", "options": {"path": str(tmp_path / "results.sqlite")}},
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
    assert "outcome: timeout after 2 steps" in out and "no detail" not in out
    assert "flatland/arm/condition/0 (seed " in out


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


CELLS = [("OF", arm, condition) for arm in ("baseline", "safeembodai")
         for condition in ("no_attack", "template_injection")]


@pytest.fixture
def ablation_dir(tmp_path):
    """A run folder like an ablation's: trials 0 to 3 in each of 4 cells, stored and closed."""
    from safeembodai_core.models import Outcome, TrialResult, TrialSpec
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    store = SqliteStateStore(tmp_path / "results.sqlite")
    for environment, arm, condition in CELLS:
        for index in range(4):
            spec = TrialSpec(trial_id=f"{environment}/{arm}/{condition}/{index}", environment=environment, arm=arm,
                             condition=condition, index=index, seed=2**62 + index)
            store.begin_trial(spec)
            store.end_trial(TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=index, detail="reached the can"))
    store.close()
    return tmp_path


def test_an_index_in_several_cells_lists_the_full_ids_and_exits_non_zero(ablation_dir):
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "show", str(ablation_dir), "--trial", "3"],
                          capture_output=True, text=True, timeout=120)
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert "exists in 4 cells" in done.stderr
    listed = [line.strip() for line in done.stderr.splitlines()[1:]]
    assert listed == [f"{e}/{a}/{c}/3" for e, a, c in CELLS]


def test_cell_filters_or_a_full_id_pick_one_trial(cli_runner, ablation_dir):
    narrowed = invoke(cli_runner, ablation_dir, "--trial", "3", "--environment", "OF", "--arm", "safeembodai",
                      "--condition", "no_attack")
    assert narrowed.exit_code == 0, narrowed.output
    assert "OF/safeembodai/no_attack/3" in narrowed.output and "after 3 steps (reached the can)" in narrowed.output
    one = invoke(cli_runner, ablation_dir, "--trial", "OF/baseline/no_attack/1")
    assert one.exit_code == 0, one.output
    assert "after 1 step (reached the can)" in one.output


@pytest.mark.parametrize("width", [80, 30])
def test_the_listing_never_cuts_a_trial_id(ablation_dir, width):
    from rich.console import Console

    from safeembodai_plugins.state.review import show_run

    console = Console(width=width, record=True, color_system=None)
    show_run(str(ablation_dir), None, console=console)
    lines = console.export_text().splitlines()
    ids = {line.split()[0] for line in lines if line.strip()}
    assert {f"{e}/{a}/{c}/{i}" for e, a, c in CELLS for i in range(4)} <= ids
    if width == 80:
        assert max(map(len, lines)) <= 80


def test_show_leaves_nothing_behind_in_the_folder_it_reads(cli_runner, ablation_dir):
    before = sorted(path.name for path in ablation_dir.iterdir())
    assert invoke(cli_runner, ablation_dir).exit_code == 0
    assert invoke(cli_runner, ablation_dir, "--trial", "OF/baseline/no_attack/2").exit_code == 0
    assert sorted(path.name for path in ablation_dir.iterdir()) == before


def test_show_reads_a_run_whose_writer_is_still_open(cli_runner, tmp_path):
    """A live run's last trials are still in the -wal file: a read-only look must see them too."""
    from safeembodai_core.models import Outcome, TrialResult, TrialSpec
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    store = SqliteStateStore(tmp_path / "results.sqlite")
    try:
        spec = TrialSpec(trial_id="OF/a/c/0", environment="OF", arm="a", condition="c", seed=1)
        store.begin_trial(spec)
        store.end_trial(TrialResult(spec=spec, outcome=Outcome.TIMEOUT, steps=2))
        assert (tmp_path / "results.sqlite-wal").exists()
        result = invoke(cli_runner, tmp_path)
        assert result.exit_code == 0, result.output
        assert "OF/a/c/0" in result.output and "timeout" in result.output
    finally:
        store.close()


@pytest.mark.parametrize("backend, banner", [("mock", "SIMULATED PILOT (MOCK): NOT A MEASUREMENT OF AN LLM"),
                                             ("scripted", None)])
def test_show_says_whether_a_simulated_pilot_answered(cli_runner, repo, tmp_path, backend, banner):
    runs = tmp_path / "runs"
    chosen = ["--backend", backend] if backend == "mock" else []  # quickstart's own pilot is scripted
    done = cli_runner.invoke(cli, ["ablate", str(repo / "scenarios/quickstart.yaml"), *chosen, "--set", "trials=1",
                                   "--set", "max_steps=2",
                                   "--no-report", "--out", str(runs)])
    assert done.exit_code == 0, done.output
    [run] = runs.iterdir()
    shown = invoke(cli_runner, run, "--trial", "0", "--arm", "baseline", "--condition", "no_attack")
    assert shown.exit_code == 0, shown.output
    assert (banner in shown.output) if banner else ("simulated pilot" not in shown.output.lower())
    bare = invoke(cli_runner, run / "results.sqlite", "--trial", "0", "--arm", "baseline", "--condition", "no_attack")
    assert "may have been a simulated pilot" in " ".join(bare.output.split())


ENDLESS_STEPS = ("CREATE VIEW steps AS WITH RECURSIVE n(i) AS (SELECT 1 UNION ALL SELECT i + 1 FROM n) "
                 "SELECT t.trial_id AS trial_id, n.i AS step, 1 AS accepted, 0 AS attacked, 0 AS flagged, "
                 "0 AS prompt_tokens, 0 AS completion_tokens, '{}' AS record FROM trials AS t, n")


@pytest.mark.timeout(20)
@pytest.mark.parametrize("swap", [
    ("DROP TABLE steps", ENDLESS_STEPS),  # a view yielding rows forever
    ("DROP TABLE attacks", "CREATE TABLE attacks (trial_id TEXT)"),  # a table without the expected columns
])
def test_a_store_whose_tables_are_not_the_schemas_is_refused_before_any_row_is_read(cli_runner, ablation_dir,
                                                                                   swap):
    import sqlite3

    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    path = ablation_dir / "results.sqlite"
    conn = sqlite3.connect(path)
    for statement in swap:
        conn.execute(statement)
    conn.commit()
    conn.close()
    result = invoke(cli_runner, ablation_dir, "--trial", "OF/baseline/no_attack/1")
    said = result.output + str(result.exception)  # the command line prints the error without a traceback
    assert result.exit_code != 0 and "not a SafeEmbodAI results database" in said and str(path) in said
    for readonly in (True, False):
        with pytest.raises(StateStoreError, match="not a SafeEmbodAI results database") as refused:
            SqliteStateStore(path, readonly=readonly)
        assert str(path) in str(refused.value)
