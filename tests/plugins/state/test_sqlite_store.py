"""The ``sqlite`` store: WAL, per-step transactions, parallel writers, crashes, bad files, secrets."""

from __future__ import annotations

import multiprocessing
import pickle
import sqlite3
import subprocess
import sys
import textwrap

import pytest

from safeembodai_core.contracts.components import BuildContext
from safeembodai_core.errors import StateStoreError
from safeembodai_core.models import Outcome, StepRecord, TrialResult
from safeembodai_core.testing import answer, run_tiny_trial, turn
from safeembodai_plugins.state.sqlite_db import SCHEMA_VERSION, SqliteStateStore

from .test_state_stores import SPEC, make_step


def open_store(plugins, path, **options):
    return plugins.registry.build("state_store", "sqlite", {"path": str(path), **options})


def test_file_is_wal_with_a_versioned_schema(plugins, tmp_path):
    open_store(plugins, tmp_path / "a.sqlite").close()
    conn = sqlite3.connect(tmp_path / "a.sqlite")
    assert conn.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert conn.execute("SELECT value FROM meta WHERE key='schema_version'").fetchone()[0] == str(SCHEMA_VERSION)


def test_default_path_is_results_sqlite_in_the_run_folder(plugins, tmp_path):
    context = BuildContext(component="sqlite", kind="state_store", run_dir=str(tmp_path / "run"))
    store = plugins.registry.build("state_store", "sqlite", {}, context)
    store.begin_trial(SPEC)
    store.close()
    assert (tmp_path / "run" / "results.sqlite").is_file()


def test_no_path_and_no_run_folder_is_a_clear_error(plugins):
    with pytest.raises(StateStoreError, match="no 'path' option and no run folder"):
        plugins.registry.build("state_store", "sqlite", {})


def test_flattened_tables_mirror_the_records(plugins, tmp_path):
    store = open_store(plugins, tmp_path / "a.sqlite")
    store.begin_trial(SPEC)
    for i in (1, 2, 3):
        store.record_step(make_step(i))
    store.close()
    conn = sqlite3.connect(tmp_path / "a.sqlite")
    assert conn.execute("SELECT COUNT(*) FROM attempts").fetchone()[0] == 6
    assert conn.execute("SELECT step FROM attacks ORDER BY step").fetchall() == [(1,), (3,)]
    assert conn.execute("SELECT rule, valid FROM verdicts WHERE step = 2").fetchall() == [("lidar_clearance", 1)]
    assert conn.execute("SELECT SUM(prompt_tokens) FROM steps").fetchone()[0] == 3 * (500 + 510)
    assert conn.execute("SELECT status FROM trials").fetchall() == [("running",)]


def _writer(store: SqliteStateStore, worker: int, barrier, trials: int, steps: int) -> None:
    barrier.wait()
    for t in range(trials):
        spec = SPEC.model_copy(update={"trial_id": f"w{worker}/t{t}", "index": t})
        store.begin_trial(spec)
        for i in range(1, steps + 1):
            store.record_step(make_step(i, trial_id=spec.trial_id, distance=float(worker * 100 + i)))
        store.end_trial(TrialResult(spec=spec, outcome=Outcome.TIMEOUT, steps=steps))
    store.close()


def test_several_processes_write_different_trials_at_once(plugins, tmp_path):
    path = tmp_path / "shared.sqlite"
    store = open_store(plugins, path, timeout_s=60)
    ctx = multiprocessing.get_context("fork")  # workers inherit the store object, as executors hand it over
    workers, trials, steps = 3, 2, 12
    barrier = ctx.Barrier(workers)
    processes = [ctx.Process(target=_writer, args=(store, w, barrier, trials, steps)) for w in range(workers)]
    for process in processes:
        process.start()
    for process in processes:
        process.join(120)
    assert [p.exitcode for p in processes] == [0] * workers
    for w in range(workers):
        for t in range(trials):
            records = store.steps(f"w{w}/t{t}")
            assert [r.step for r in records] == list(range(1, steps + 1))
            assert ([r.executed[-1].signal.distance for r in records]
                    == [float(w * 100 + i) for i in range(1, steps + 1)])
    conn = sqlite3.connect(path)
    assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert conn.execute("SELECT COUNT(*) FROM steps").fetchone()[0] == workers * trials * steps
    assert conn.execute("SELECT COUNT(*) FROM trials WHERE status = 'finished'").fetchone()[0] == workers * trials


CRASH = textwrap.dedent("""
    import os, sys
    from safeembodai_core.models import StepRecord, TrialSpec
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    store = SqliteStateStore(sys.argv[1])
    spec = TrialSpec(trial_id="t", environment="e", arm="a", condition="c", seed=1)
    store.begin_trial(spec)
    for step in (1, 2):
        store.record_step(StepRecord(trial_id="t", step=step, instruction=f"step {step}"))
    transaction = SqliteStateStore._transaction

    def write_then_die(self, doing, work):
        def rows_then_exit(conn):
            work(conn)  # every row of the step is written, the commit never comes
            os._exit(17)

        transaction(self, doing, rows_then_exit)

    SqliteStateStore._transaction = write_then_die
    store.record_step(StepRecord(trial_id="t", step=3, instruction="step 3"))
""")


def test_a_crash_mid_step_loses_only_that_step(tmp_path):
    path = tmp_path / "crash.sqlite"
    done = subprocess.run([sys.executable, "-c", CRASH, str(path)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 17, done.stderr
    store = SqliteStateStore(path)
    assert [r.instruction for r in store.steps("t")] == ["step 1", "step 2"]
    assert store.reference_state("t", 3).step == 2
    store.record_step(StepRecord(trial_id="t", step=3, instruction="step 3 again"))
    assert [r.step for r in store.steps("t")] == [1, 2, 3]
    assert sqlite3.connect(path).execute("PRAGMA integrity_check").fetchone()[0] == "ok"


def test_a_locked_database_is_a_clear_error_and_loses_nothing(plugins, tmp_path):
    path = tmp_path / "locked.sqlite"
    store = open_store(plugins, path, timeout_s=0.2)
    store.begin_trial(SPEC)
    store.record_step(make_step(1))
    blocker = sqlite3.connect(path, isolation_level=None)
    blocker.execute("BEGIN EXCLUSIVE")
    try:
        with pytest.raises(StateStoreError, match=r"locked\.sqlite'.*locked by another process"):
            store.record_step(make_step(2))
    finally:
        blocker.execute("ROLLBACK")
        blocker.close()
    assert [r.step for r in store.steps(SPEC.trial_id)] == [1]
    store.record_step(make_step(2))
    assert [r.step for r in store.steps(SPEC.trial_id)] == [1, 2]


def test_a_file_that_is_not_a_database_is_a_clear_error(plugins, tmp_path):
    path = tmp_path / "garbage.sqlite"
    path.write_bytes(b"this is not a database at all " * 200)
    with pytest.raises(StateStoreError, match=r"garbage\.sqlite'.*not a SQLite database"):
        open_store(plugins, path)
    assert path.read_bytes().startswith(b"this is not a database")  # nothing overwritten


def test_a_foreign_database_or_another_schema_version_is_refused(plugins, tmp_path):
    foreign = tmp_path / "foreign.sqlite"
    sqlite3.connect(foreign).execute("CREATE TABLE users (name TEXT)")
    with pytest.raises(StateStoreError, match=r"foreign\.sqlite'.*not a SafeEmbodAI results database.*users"):
        open_store(plugins, foreign)
    newer = tmp_path / "newer.sqlite"
    open_store(plugins, newer).close()
    conn = sqlite3.connect(newer)
    conn.execute("UPDATE meta SET value = '99' WHERE key = 'schema_version'")
    conn.commit()
    with pytest.raises(StateStoreError, match=r"newer\.sqlite'.*schema version 99"):
        open_store(plugins, newer)


def test_the_store_pickles_without_its_connection(plugins, tmp_path):
    store = open_store(plugins, tmp_path / "p.sqlite")
    store.begin_trial(SPEC)
    store.record_step(make_step(1))
    copy = pickle.loads(pickle.dumps(store))
    copy.record_step(make_step(2))
    assert [r.step for r in store.steps(SPEC.trial_id)] == [1, 2]


def test_no_secret_is_stored_and_other_text_stays_as_written(tmp_path, monkeypatch):
    secret = "sk-live-ENVIRONMENTSECRET0123456789"
    monkeypatch.setenv("OPENAI_API_KEY", secret)
    monkeypatch.setenv("SAFEEMBODAI_TEST_TOKEN", secret + "-2")
    key_like = "sk-abcdefghijklmnopqrstuvwx"
    prose = f"the operator's note said {key_like}; NUL\x00 ESC\x1b[2J tab\t"
    run_tiny_trial([prose, answer(turn(10))], max_steps=2,
                   state={"use": "sqlite", "options": {"path": str(tmp_path / "s.sqlite")}},
                   attackers=[{"use": "prompt_injection", "options": {"rate": 1.0}}])
    written = b"".join(path.read_bytes() for path in tmp_path.iterdir() if path.is_file())
    assert b"ENVIRONMENTSECRET" not in written and b"abcdefghijklmnopqrstuvwx" not in written
    steps = SqliteStateStore(tmp_path / "s.sqlite").steps("flatland/arm/condition/0")
    # masked; everything else as the LLM wrote it (the display escapes it, not the store)
    assert steps[0].attempts[0].raw_text == "the operator's note said ***; NUL\x00 ESC\x1b[2J tab\t"
    assert steps[0].accepted and steps[0].attacks


def _open_new_store(path, barrier, queue):
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    barrier.wait()
    try:
        SqliteStateStore(path, timeout_s=30)._connection()
        queue.put(None)
    except Exception as error:  # reported to the parent, which asserts on it
        queue.put(repr(error))


@pytest.mark.slow
def test_many_processes_can_create_the_same_new_file_at_once(tmp_path):
    import multiprocessing

    context = multiprocessing.get_context("fork")
    errors = []
    for round_ in range(12):
        path = tmp_path / f"new-{round_}.sqlite"
        barrier, queue = context.Barrier(10), context.Queue()
        workers = [context.Process(target=_open_new_store, args=(path, barrier, queue)) for _ in range(10)]
        for worker in workers:
            worker.start()
        errors += [e for e in (queue.get(timeout=60) for _ in workers) if e]
        for worker in workers:
            worker.join()
    assert errors == []


# -- what the store remembers of its own writes (issue 51) ----------------------------------------

def statements(store: SqliteStateStore) -> list[str]:
    """Every SQL statement the store's connection runs from now on (its first words)."""
    seen: list[str] = []
    store._connection().set_trace_callback(lambda sql: seen.append(" ".join(sql.split()[:3])))
    return seen


def test_a_steps_first_write_after_its_trial_began_deletes_nothing_and_a_rewrite_replaces(tmp_path):
    store = SqliteStateStore(tmp_path / "own.sqlite")
    store.begin_trial(SPEC)
    seen = statements(store)
    store.record_step(make_step(1))
    assert not [s for s in seen if s.startswith("DELETE")]  # the trial it began has no row of step 1 yet
    seen.clear()
    store.record_step(make_step(1, distance=250.0).model_copy(update={"attempts": make_step(1).attempts[:1]}))
    assert len([s for s in seen if s.startswith("DELETE")]) == 4  # the step again: every table's rows replaced
    rows = sqlite3.connect(tmp_path / "own.sqlite").execute("SELECT COUNT(*) FROM attempts").fetchone()[0]
    assert rows == 1 and store.steps(SPEC.trial_id)[0].executed[1].signal.distance == 250.0


def test_a_store_that_did_not_begin_the_trial_replaces_what_another_wrote(tmp_path):
    path = tmp_path / "two.sqlite"
    first = SqliteStateStore(path)
    first.begin_trial(SPEC)
    first.record_step(make_step(1))
    second = SqliteStateStore(path)  # began nothing: it cannot know what the file holds
    second.record_step(make_step(1).model_copy(update={"attempts": [], "attacks": []}))
    conn = sqlite3.connect(path)
    assert [conn.execute(f"SELECT COUNT(*) FROM {table}").fetchone()[0]
            for table in ("steps", "attempts", "verdicts", "attacks")] == [1, 0, 0, 0]
    copy = pickle.loads(pickle.dumps(first))  # a copy in another process remembers nothing either
    assert copy._began == {} and copy._last_step == {}


def test_the_previous_step_is_read_back_from_the_text_written_as_the_file_holds_it(tmp_path):
    path = tmp_path / "reference.sqlite"
    writer = SqliteStateStore(path)
    writer.begin_trial(SPEC)
    writer.record_step(make_step(1))
    writer.record_step(make_step(2, distance=333.0))
    seen = statements(writer)
    remembered = writer.reference_state(SPEC.trial_id, 3)
    assert not seen  # no query: the text this store wrote
    assert remembered == SqliteStateStore(path, readonly=True).reference_state(SPEC.trial_id, 3)
    assert remembered.step == 2
    assert writer.reference_state(SPEC.trial_id, 2).step == 1  # an older step: read from the file
    assert seen


def test_a_write_that_failed_leaves_the_store_replacing_again(tmp_path, monkeypatch):
    store = SqliteStateStore(tmp_path / "failed.sqlite")
    store.begin_trial(SPEC)

    def fail(doing, work):
        raise StateStoreError("disk full")

    with monkeypatch.context() as patch:
        patch.setattr(store, "_transaction", fail)
        with pytest.raises(StateStoreError):
            store.record_step(make_step(1))
    seen = statements(store)
    store.record_step(make_step(1))
    assert len([s for s in seen if s.startswith("DELETE")]) == 4  # what the file holds is unknown again
    assert store.reference_state(SPEC.trial_id, 2).step == 1


def test_a_forked_child_remembers_none_of_its_parents_writes(tmp_path):
    path = tmp_path / "forked.sqlite"
    store = SqliteStateStore(path)
    store.begin_trial(SPEC)
    store.record_step(make_step(1))
    fork = multiprocessing.get_context("fork")
    reader, writer = fork.Pipe(duplex=False)
    go = fork.Event()
    child = fork.Process(target=_child_writes_step_2, args=(store, go, writer))
    child.start()  # the child's copy remembers the trial begun and step 1 recorded
    store.record_step(make_step(2))  # the parent's step 2, after the fork: the child's copy cannot know it
    go.set()
    child.join(60)
    assert child.exitcode == 0 and reader.recv() == "replaced"
    assert [r.executed[1].signal.distance for r in SqliteStateStore(path, readonly=True).steps(SPEC.trial_id)] == \
        [100.0, 222.0]


def _child_writes_step_2(store: SqliteStateStore, go, done) -> None:
    go.wait(60)
    try:  # trusting the parent's memory, the child would skip the DELETEs and collide with the parent's row
        store.record_step(make_step(2, distance=222.0))
    except StateStoreError as error:
        done.send(str(error))
        return
    done.send("replaced")


def test_a_record_that_cannot_be_serialised_is_an_error_naming_the_file(tmp_path):
    store = SqliteStateStore(tmp_path / "surrogate.sqlite")
    with pytest.raises(StateStoreError, match=r"surrogate\.sqlite.*cannot begin trial"):
        store.begin_trial(SPEC.model_copy(update={"trial_id": "e/a/c/\ud800"}))
