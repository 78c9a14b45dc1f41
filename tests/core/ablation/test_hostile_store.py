"""A results store from elsewhere read strictly: a row that is not a record, a row holding another
trial's result or step, two rows for one trial, a table that yields rows forever -- each a clean
error naming the file, table and row, in bounded time; the CLI says it in one line, exit 1."""

from __future__ import annotations

import sqlite3
import time

import pytest

import safeembodai_plugins.state.sqlite_db as sqlite_db
from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.cli import main
from safeembodai_core.errors import StateStoreError
from safeembodai_core.scenario import load_scenario
from safeembodai_plugins.state.sqlite_db import SqliteStateStore


@pytest.fixture
def run(repo, plugins, tmp_path):
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=2"], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(tmp_path / "run"))
    try:
        results = ablation.run()
    finally:
        ablation.close()
    return tmp_path / "run", [r.spec.trial_id for r in results]


def _edit(folder, *statements):
    conn = sqlite3.connect(folder / "results.sqlite")
    for sql, args in statements:
        conn.execute(sql, args)
    conn.commit()
    conn.close()


def _error(folder, read) -> str:
    store = SqliteStateStore(folder / "results.sqlite", readonly=True)
    try:
        with pytest.raises(StateStoreError) as error:
            read(store)
    finally:
        store.close()
    return str(error.value)


def test_a_result_that_is_not_json_names_the_file_table_and_row(run):
    folder, ids = run
    _edit(folder, ("UPDATE trials SET result = ? WHERE trial_id = ?", ("{not json", ids[0])))
    message = _error(folder, lambda s: s.results())
    assert "results.sqlite" in message and "table trials" in message and ids[0] in message
    assert "is not a TrialResult" in message


def test_a_row_holding_another_trials_result_is_refused_not_counted_twice(run):
    folder, ids = run
    conn = sqlite3.connect(folder / "results.sqlite")
    other = conn.execute("SELECT result FROM trials WHERE trial_id = ?", (ids[1],)).fetchone()[0]
    conn.close()
    _edit(folder, ("UPDATE trials SET result = ? WHERE trial_id = ?", (other, ids[0])))
    assert f"holds the result of trial {ids[1]!r}" in _error(folder, lambda s: s.results())
    assert f"holds the result of trial {ids[1]!r}" in _error(folder, lambda s: s.result(ids[0]))


def test_a_step_row_of_another_step_or_not_a_record_is_refused(run):
    folder, ids = run
    _edit(folder, ("UPDATE steps SET step = 7 WHERE trial_id = ? AND step = 1", (ids[0],)))
    assert "holds step 1" in _error(folder, lambda s: s.steps(ids[0]))
    _edit(folder, ("UPDATE steps SET record = ? WHERE trial_id = ? AND step = 7", (b"\x00\xff", ids[0])))
    assert "table steps" in _error(folder, lambda s: s.steps(ids[0]))
    _edit(folder, ("UPDATE steps SET record = 42 WHERE trial_id = ? AND step = 7", (ids[0],)))
    assert "record is not a StepRecord" in _error(folder, lambda s: s.steps(ids[0]))


#: ``trials`` as the schema declares it, less its primary key: what a forged store may hold
_TRIALS_WITHOUT_KEY = ("CREATE TABLE trials (trial_id TEXT, scenario TEXT NOT NULL, environment TEXT NOT NULL, "
                       "arm TEXT NOT NULL, condition TEXT NOT NULL, trial_index INTEGER NOT NULL, "
                       "seed INTEGER NOT NULL, status TEXT NOT NULL, outcome TEXT, steps INTEGER, spec TEXT NOT NULL, "
                       "result TEXT)")


def test_two_rows_for_one_trial_are_refused(run):
    folder, ids = run
    _edit(folder, ("ALTER TABLE trials RENAME TO trials_kept", ()), (_TRIALS_WITHOUT_KEY, ()),
          ("INSERT INTO trials SELECT * FROM trials_kept", ()), ("INSERT INTO trials SELECT * FROM trials_kept", ()))
    assert "has two rows" in _error(folder, lambda s: s.results())


def _view(rows_sql: str) -> str:
    return ("CREATE VIEW trials AS WITH RECURSIVE n(k) AS (SELECT 1 UNION ALL SELECT k + 1 FROM n" + rows_sql + ") "
            "SELECT 'x' || k AS trial_id, 'e' AS environment, 'a' AS arm, 'c' AS condition, k AS trial_index, "
            "'finished' AS status, '{}' AS result FROM n")


def test_a_table_too_long_stops_at_the_row_bound_and_an_endless_view_is_refused_at_once(run, monkeypatch):
    folder, _ = run
    _edit(folder, ("ALTER TABLE trials RENAME TO trials_kept", ()), (_TRIALS_WITHOUT_KEY, ()),
          ("WITH RECURSIVE n(k) AS (SELECT 1 UNION ALL SELECT k + 1 FROM n WHERE k < 30000) INSERT INTO trials "
           "SELECT 'x' || k, 's', 'e', 'a', 'c', k, 0, 'finished', NULL, 0, '{}', '{}' FROM n", ()))
    monkeypatch.setattr(sqlite_db, "MAX_ROWS", 20_000)
    assert "more than 20,000 rows" in _error(folder, lambda s: s.results())
    monkeypatch.setattr(sqlite_db, "MAX_ROWS", 1_000_000)
    monkeypatch.setattr(sqlite_db, "MAX_QUERY_S", 1e-4)  # the time bound, on a table slow enough to pass it
    assert "took more than" in _error(folder, lambda s: s.results())
    _edit(folder, ("DROP TABLE trials", ()), (_view(""), ()))  # rows forever: refused before any is read
    start = time.monotonic()
    with pytest.raises(StateStoreError, match="'trials' is a view, not a table"):
        SqliteStateStore(folder / "results.sqlite", readonly=True)
    assert time.monotonic() - start < 5


def test_report_and_show_say_it_in_one_line(run, capsys):
    folder, ids = run
    _edit(folder, ("UPDATE trials SET result = '[]' WHERE trial_id = ?", (ids[0],)))
    site = str(folder.parent / "s")
    commands = (["report", str(folder)], ["show", str(folder), "--trial", ids[0]], ["view", str(folder), "--out", site])
    for args in commands:
        with pytest.raises(SystemExit) as done:
            main(args)
        err = capsys.readouterr().err
        assert done.value.code == 1 or "table trials" in (folder.parent / "s" / "index.html").read_text(), err
        assert "Traceback" not in err
        if done.value.code == 1:
            [line] = [line for line in err.splitlines() if line.startswith("Error: ")]
            assert "table trials" in line and ids[0] in line


@pytest.mark.parametrize("name", ["scenario.json", "finished.jsonl", "response_cache.json"])
@pytest.mark.parametrize("kind", ["fifo", "symlink", "folder"])
def test_a_run_file_that_is_not_a_regular_file_is_refused_at_once(run, capsys, name, kind):
    import os

    folder, _ = run
    target = folder / name
    target.unlink(missing_ok=True)
    if kind == "fifo":
        os.mkfifo(target)  # a plain open() would wait here for a writer forever
    elif kind == "symlink":
        secret = folder.parent / "secret.json"
        secret.write_text("{}")
        target.symlink_to(secret)
    else:
        target.mkdir()
    start = time.monotonic()
    with pytest.raises(SystemExit) as done:
        main(["ablate", "--resume", str(folder), "--no-report"])
    err = capsys.readouterr().err
    assert done.value.code == 1 and time.monotonic() - start < 30
    [line] = [line for line in err.splitlines() if line.startswith("Error: ")]
    assert name in line and "unreadable" in line and "Traceback" not in err
