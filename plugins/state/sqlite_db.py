"""The SQLite state store: schema, one transaction per step, clear errors naming the file.

Layout (schema version :data:`SCHEMA_VERSION`, kept in table ``meta``):

* ``trials`` -- one row per trial: its spec, ``status`` (``running`` / ``finished``), outcome
  and :class:`TrialResult` (JSON);
* ``steps`` -- one row per step: the full :class:`StepRecord` as JSON (the source of truth, read
  back unchanged) plus summary columns (accepted, attacked, flagged, tokens) for SQL queries;
* ``attempts``, ``verdicts``, ``attacks`` -- the same facts flattened, for analysis in SQL (the
  report's refusals per rule and attack kinds, :meth:`SqliteStateStore.step_facts`, are two
  aggregate queries over ``verdicts`` and ``attacks``: no step record is parsed).

Durability: WAL journal, ``BEGIN IMMEDIATE ... COMMIT`` per step. A process that dies in the
middle of a step leaves that step's transaction uncommitted, so it vanishes on the next open;
every earlier step stays. Writers in other processes wait up to ``timeout_s`` for the lock.

Re-recording a step replaces it: the loop writes a step with an accepted plan twice, before
execution (``status`` ``executing``) and after (``done``), each in its own transaction.

Under the lock only SQL runs: records are serialised into their rows before it is taken (issue
51: with 64 trials in threads, every other thread holding the GIL while the lock-holder waits to
get it back made the lock the step's longest wait). The store remembers what it wrote itself: a
trial it began holds no rows but the ones it recorded since, so a step's first write deletes
nothing, and the previous step's record (``reference_state``) is read back from the text it wrote,
through the same strict reading as a row. A forked or unpickled copy remembers nothing. This
assumes what a run guarantees: one writer per trial (its lock, and each trial on one worker);
another writer's rows for a trial this store began are not seen, and a step it then writes first
fails loudly on the steps table's key rather than leaving two.

What is written: the fields of the records the store is handed and nothing else (no options, no
environment), as :func:`~safeembodai_core.trust.text.storable` copies -- secrets redacted, lone
surrogates replaced, integers within SQLite's range -- so what an answer holds cannot make a
write fail. Otherwise text is stored as written (NUL and escape sequences included).
"""

from __future__ import annotations

import os
import sqlite3
import threading
import time
from pathlib import Path
from typing import Any, Callable, Iterable, Iterator

from pydantic import ValidationError

from safeembodai_core.contracts.components import StateStore, StepFacts
from safeembodai_core.errors import StateStoreError
from safeembodai_core.models import ReferenceState, StepRecord, TrialResult, TrialSpec
from safeembodai_core.trust.text import storable

SCHEMA_VERSION = 1
#: The longest any one read may take, and the most rows it may return (far beyond a real run's).
MAX_QUERY_S = 120.0
MAX_ROWS = 5_000_000

SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS trials (
    trial_id TEXT PRIMARY KEY, scenario TEXT NOT NULL, environment TEXT NOT NULL, arm TEXT NOT NULL,
    condition TEXT NOT NULL, trial_index INTEGER NOT NULL, seed INTEGER NOT NULL,
    status TEXT NOT NULL, outcome TEXT, steps INTEGER, spec TEXT NOT NULL, result TEXT);
CREATE TABLE IF NOT EXISTS steps (
    trial_id TEXT NOT NULL, step INTEGER NOT NULL, accepted INTEGER NOT NULL, attacked INTEGER NOT NULL,
    flagged INTEGER NOT NULL, prompt_tokens INTEGER NOT NULL, completion_tokens INTEGER NOT NULL,
    record TEXT NOT NULL, PRIMARY KEY (trial_id, step));
CREATE TABLE IF NOT EXISTS attempts (
    trial_id TEXT NOT NULL, step INTEGER NOT NULL, attempt INTEGER NOT NULL, accepted INTEGER NOT NULL,
    parse_error TEXT, planning TEXT, prompt_tokens INTEGER NOT NULL, completion_tokens INTEGER NOT NULL,
    latency_s REAL NOT NULL, PRIMARY KEY (trial_id, step, attempt));
CREATE TABLE IF NOT EXISTS verdicts (
    trial_id TEXT NOT NULL, step INTEGER NOT NULL, attempt INTEGER NOT NULL, signal_index INTEGER,
    rule TEXT NOT NULL, valid INTEGER NOT NULL, reason TEXT NOT NULL);
CREATE INDEX IF NOT EXISTS verdicts_by_step ON verdicts (trial_id, step);
CREATE TABLE IF NOT EXISTS attacks (
    trial_id TEXT NOT NULL, step INTEGER NOT NULL, attacker TEXT NOT NULL, channel TEXT NOT NULL,
    kind TEXT NOT NULL, payload TEXT NOT NULL);
CREATE INDEX IF NOT EXISTS attacks_by_step ON attacks (trial_id, step);
"""
_PER_STEP_TABLES = ("steps", "attempts", "verdicts", "attacks")
#: per trial and rule, the attempts the rule refused (an attempt counts once per rule)
_REFUSALS = ("SELECT trial_id, rule, COUNT(*) FROM (SELECT DISTINCT trial_id, step, attempt, rule FROM verdicts "
             "WHERE valid = 0) GROUP BY trial_id, rule")
#: per trial and attack kind, the steps attacked with that kind
_ATTACKS = ("SELECT trial_id, kind, COUNT(*) FROM (SELECT DISTINCT trial_id, step, kind FROM attacks) "
            "GROUP BY trial_id, kind")
_EXPECTED: dict[str, tuple[tuple[str, str], ...]] = {}  # table -> (column, declared type), from SCHEMA
_INHERITED: list[sqlite3.Connection] = []  # kept alive so a forked child never closes its parent's handle


def _columns(conn: sqlite3.Connection, table: str) -> tuple[tuple[str, str], ...]:
    return tuple((row[1], str(row[2]).upper()) for row in conn.execute("SELECT * FROM pragma_table_info(?)", (table,)))


def expected_tables() -> dict[str, tuple[tuple[str, str], ...]]:
    """Each table of :data:`SCHEMA` and its columns (name, declared type), read from a database
    made with it, so the check and the schema cannot disagree."""
    if not _EXPECTED:
        conn = sqlite3.connect(":memory:")
        try:
            conn.executescript(SCHEMA)
            names = [row[0] for row in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")]
            _EXPECTED.update({name: _columns(conn, name) for name in names})
        finally:
            conn.close()
    return _EXPECTED


class SqliteStateStore(StateStore):
    """Step records and R_{i-1} in one SQLite file; see the module docstring.

    The connection is opened lazily and again after a ``fork``, so one store object may be handed
    to worker processes (it pickles without its connection).
    """

    def __init__(self, path: str | Path, *, timeout_s: float = 30.0, synchronous: str = "normal",
                 readonly: bool = False) -> None:
        self.path = Path(path)
        self.timeout_s = timeout_s
        self.synchronous = synchronous.upper()
        if self.synchronous not in ("NORMAL", "FULL"):
            raise ValueError(f"synchronous must be 'normal' or 'full', got {synchronous!r}")
        self.readonly = readonly
        self._conn: sqlite3.Connection | None = None
        self._pid = -1
        self._lock = threading.Lock()
        self._forget_own_writes()
        self._connection()  # fail now, naming the file, not at the first step

    def _forget_own_writes(self) -> None:
        """What this object (in this process) wrote, see the module docstring: per trial it began,
        the steps it has recorded since; per trial, its last recorded step's number and JSON."""
        self._began: dict[str, set[int]] = {}
        self._last_step: dict[str, tuple[int, str]] = {}
        self._writes_pid = os.getpid()

    def _own_writes(self) -> tuple[dict[str, set[int]], dict[str, tuple[int, str]]]:
        """What this object wrote in this process; nothing in a forked child (it has not written yet)."""
        if self._writes_pid != os.getpid():
            self._forget_own_writes()
        return self._began, self._last_step

    def _serialised(self, doing: str, make: Callable[[], Any]) -> Any:
        """``make()``, the rows a write will hold, built before the lock; a record that cannot be
        serialised is an error naming the file, as a failed write is."""
        try:
            return make()
        except (OverflowError, ValueError) as error:  # pydantic's serialisation errors are ValueErrors
            raise self._error(doing, error) from None

    # -- connection and errors ------------------------------------------------------------------

    def __getstate__(self) -> dict[str, Any]:
        state = self.__dict__.copy()
        state.update(_conn=None, _pid=-1, _lock=None, _began={}, _last_step={}, _writes_pid=-1)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self._lock = threading.Lock()
        self._forget_own_writes()

    def _error(self, doing: str, error: BaseException) -> StateStoreError:
        text = str(error)
        if "locked" in text or "busy" in text:
            hint = f"locked by another process (waited {self.timeout_s:g} s; raise timeout_s or stop the other writer)"
        elif "not a database" in text or "malformed" in text:
            hint = "not a SQLite database, or corrupt"
        elif "readonly" in text or "unable to open" in text:
            hint = "cannot be opened for writing (permissions? missing folder?)"
        else:
            hint = text
        return StateStoreError(f"state store {str(self.path)!r}: cannot {doing}: {hint} ({text})")

    def _connection(self) -> sqlite3.Connection:
        if self._conn is not None and self._pid == os.getpid():
            return self._conn
        if self._conn is not None:  # inherited through fork: never use or close the parent's handle
            _INHERITED.append(self._conn)
        self._conn = None
        try:
            if self.readonly:
                if not self.path.is_file():
                    raise StateStoreError(f"state store {str(self.path)!r}: no such database file")
                conn = sqlite3.connect(self._readonly_uri(), uri=True, timeout=self.timeout_s, isolation_level=None,
                                       check_same_thread=False)
            else:
                self.path.parent.mkdir(parents=True, exist_ok=True)
                conn = sqlite3.connect(str(self.path), timeout=self.timeout_s, isolation_level=None,
                                       check_same_thread=False)
                self._switch_to_wal(conn)
                conn.execute(f"PRAGMA synchronous={self.synchronous}")
            try:
                self._check_schema(conn)
            except BaseException:
                conn.close()
                raise
        except sqlite3.Error as error:
            raise self._error("open the database", error) from None
        except OSError as error:
            raise self._error("open the database", error) from None
        self._conn, self._pid = conn, os.getpid()
        return conn

    def _readonly_uri(self) -> str:
        """Read without leaving anything behind in a folder that is only being looked at.

        A read-only connection to a WAL database creates ``-wal`` and ``-shm`` files and, unable to
        checkpoint, never removes them. Without a ``-wal`` file no writer has the database open (a
        writer's connection keeps one; the last writer to close removes it), so the file is opened
        ``immutable``: no lock, no journal, nothing created. With one (a run still writing, or a
        writer that was killed), ``mode=ro`` reads the log too, sharing the files that already exist.
        """
        uri = self.path.resolve().as_uri() + "?mode=ro"
        if not Path(f"{self.path}-wal").exists():
            uri += "&immutable=1"
        return uri

    def _switch_to_wal(self, conn: sqlite3.Connection) -> None:
        """Enable WAL, waiting up to ``timeout_s`` for other processes creating the same file.

        SQLite answers "database is locked" at once here, without its busy timeout, while another
        connection switches a new file's journal mode: several workers starting together hit it.
        """
        deadline = time.monotonic() + self.timeout_s
        while True:
            try:
                conn.execute("PRAGMA journal_mode=WAL")
                return
            except sqlite3.OperationalError as error:
                if "locked" not in str(error) or time.monotonic() >= deadline:
                    raise
                time.sleep(0.02)

    def _check_schema(self, conn: sqlite3.Connection) -> None:
        tables = {row[0] for row in conn.execute("SELECT name FROM sqlite_master WHERE type='table'")}
        if not tables and not self.readonly:
            conn.execute("BEGIN IMMEDIATE")  # several workers may create the same file at once
            try:
                for statement in filter(str.strip, SCHEMA.split(";")):
                    conn.execute(statement)
                conn.execute("INSERT OR IGNORE INTO meta VALUES ('schema_version', ?)", (str(SCHEMA_VERSION),))
                conn.execute("COMMIT")
            except BaseException:
                if conn.in_transaction:
                    conn.execute("ROLLBACK")
                raise
            tables = {"meta"}
        if "meta" not in tables:
            found = ", ".join(sorted(tables)) or "none"
            raise StateStoreError(f"state store {str(self.path)!r}: "
                                  f"not a SafeEmbodAI results database (tables: {found})")
        self._check_objects(conn)
        row = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
        version = row[0] if row else None
        if version != str(SCHEMA_VERSION):
            raise StateStoreError(
                f"state store {str(self.path)!r}: schema version {version} is not the supported version "
                f"{SCHEMA_VERSION}; use a new file (or the SafeEmbodAI version that wrote it)"
            )

    def _check_objects(self, conn: sqlite3.Connection) -> None:
        """Every table of :data:`SCHEMA` is a table with its columns, checked in ``sqlite_master``
        before any row is read: a file from elsewhere whose ``steps`` is a view yielding rows
        forever (a recursive CTE) is refused at once, not after :data:`MAX_QUERY_S`."""
        kinds = {str(name).lower(): kind for name, kind in conn.execute("SELECT name, type FROM sqlite_master")}
        for table, columns in expected_tables().items():
            kind = kinds.get(table)
            if kind != "table":
                found = f"a {kind}" if kind else "missing"
                raise StateStoreError(f"state store {str(self.path)!r}: not a SafeEmbodAI results database "
                                      f"({table!r} is {found}, not a table)")
            if _columns(conn, table) != columns:
                raise StateStoreError(f"state store {str(self.path)!r}: not a SafeEmbodAI results database "
                                      f"(table {table!r} does not have the expected columns)")

    def _transaction(self, doing: str, work: Callable[[sqlite3.Connection], None]) -> None:
        """Run ``work`` in one ``BEGIN IMMEDIATE`` transaction: all of it is stored, or none."""
        if self.readonly:
            raise StateStoreError(f"state store {str(self.path)!r}: opened read-only, cannot {doing}")
        with self._lock:
            conn = self._connection()
            try:
                conn.execute("BEGIN IMMEDIATE")
                try:
                    work(conn)
                    conn.execute("COMMIT")
                except BaseException:
                    if conn.in_transaction:
                        conn.execute("ROLLBACK")
                    raise
            except (sqlite3.Error, OverflowError, ValueError) as error:  # ValueError: a record JSON cannot hold
                raise self._error(doing, error) from None

    def _query(self, doing: str, sql: str, args: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
        """Rows of one query, bounded: a file from elsewhere may make ``trials`` a view that yields rows
        forever, so a query stops with an error naming the file after :data:`MAX_QUERY_S` seconds or
        :data:`MAX_ROWS` rows."""
        with self._lock:
            conn = self._connection()
            deadline = time.monotonic() + MAX_QUERY_S
            conn.set_progress_handler(lambda: int(time.monotonic() > deadline), 10_000)
            try:
                cursor = conn.execute(sql, args)
                rows: list[tuple[Any, ...]] = []
                while batch := cursor.fetchmany(1000):
                    rows += batch
                    if len(rows) > MAX_ROWS:
                        raise StateStoreError(f"state store {str(self.path)!r}: cannot {doing}: more than "
                                              f"{MAX_ROWS:,} rows (not a run's database?)")
                return rows
            except sqlite3.OperationalError as error:
                if "interrupted" in str(error):
                    raise StateStoreError(f"state store {str(self.path)!r}: cannot {doing}: the query took more "
                                          f"than {MAX_QUERY_S:g} s (not a run's database?)") from None
                raise self._error(doing, error) from None
            except sqlite3.Error as error:
                raise self._error(doing, error) from None
            finally:
                conn.set_progress_handler(None, 0)

    def _row(self, model: Any, text: Any, table: str, key: Any, column: str) -> Any:
        """A stored record read back strictly: anything else is an error naming the file, table and row."""
        where = f"state store {str(self.path)!r}, table {table}, row {key!r}"
        if not isinstance(text, (str, bytes)):
            raise StateStoreError(f"{where}: {column} is not JSON text")
        try:
            return model.model_validate_json(text)
        except ValidationError as error:
            first = error.errors()[0]
            field = ".".join(str(part) for part in first["loc"]) or "(root)"
            raise StateStoreError(f"{where}: {column} is not a {model.__name__}: {field}: {first['msg'][:200]}") \
                from None

    def _step_row(self, trial_id: str, step: int, text: Any) -> StepRecord:
        record = self._row(StepRecord, text, "steps", (trial_id, step), "record")
        if (record.trial_id, record.step) != (trial_id, step):
            raise StateStoreError(f"state store {str(self.path)!r}, table steps, row {(trial_id, step)!r}: holds "
                                  f"step {record.step} of trial {record.trial_id!r}")
        return record

    def _result_row(self, trial_id: str, text: Any) -> TrialResult:
        result = self._row(TrialResult, text, "trials", trial_id, "result")
        if result.spec.trial_id != trial_id:
            raise StateStoreError(f"state store {str(self.path)!r}, table trials, row {trial_id!r}: holds the result "
                                  f"of trial {result.spec.trial_id!r}")
        return result

    # -- StateStore ---------------------------------------------------------------------------

    def begin_trial(self, spec: TrialSpec) -> None:
        doing = f"begin trial {spec.trial_id!r}"
        row = self._serialised(doing, lambda: (spec.trial_id, spec.scenario, spec.environment, spec.arm,
                                               spec.condition, spec.index, spec.seed, spec.model_dump_json()))

        def work(conn: sqlite3.Connection) -> None:
            for table in _PER_STEP_TABLES:
                conn.execute(f"DELETE FROM {table} WHERE trial_id = ?", (spec.trial_id,))
            conn.execute("INSERT OR REPLACE INTO trials VALUES (?, ?, ?, ?, ?, ?, ?, 'running', NULL, NULL, ?, NULL)",
                         row)

        began, last_step = self._own_writes()
        last_step.pop(spec.trial_id, None)
        began.pop(spec.trial_id, None)
        self._transaction(doing, work)
        began[spec.trial_id] = set()  # no row of the trial but the ones recorded from now on

    def record_step(self, record: StepRecord) -> None:
        record = storable(record)
        doing = f"record step {record.step} of trial {record.trial_id!r}"
        key = (record.trial_id, record.step)
        text = self._serialised(doing, record.model_dump_json)
        usage = record.usage
        step_row = key + (int(record.accepted), int(bool(record.attacks)), int(record.flagged_attack),
                          usage.prompt_tokens, usage.completion_tokens, text)
        attempts = [key + (a.index, int(a.accepted), a.parse_error,
                           a.response.planning if a.response is not None else None,
                           a.usage.prompt_tokens, a.usage.completion_tokens, a.latency_s) for a in record.attempts]
        verdicts = [key + (a.index, v.signal_index, v.rule, int(v.valid), v.reason)
                    for a in record.attempts for v in a.verdicts]
        attacks = [key + (a.attacker, a.channel, a.kind, a.payload) for a in record.attacks]
        began, last_step = self._own_writes()
        recorded = began.get(record.trial_id)
        replaces = recorded is None or record.step in recorded  # else the step has no row to replace

        def work(conn: sqlite3.Connection) -> None:
            if replaces:
                for table in _PER_STEP_TABLES:
                    conn.execute(f"DELETE FROM {table} WHERE trial_id = ? AND step = ?", key)
            conn.execute("INSERT INTO steps VALUES (?, ?, ?, ?, ?, ?, ?, ?)", step_row)
            if attempts:
                conn.executemany("INSERT INTO attempts VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)", attempts)
            if verdicts:
                conn.executemany("INSERT INTO verdicts VALUES (?, ?, ?, ?, ?, ?, ?)", verdicts)
            if attacks:
                conn.executemany("INSERT INTO attacks VALUES (?, ?, ?, ?, ?, ?)", attacks)

        try:
            self._transaction(doing, work)
        except BaseException:
            began.pop(record.trial_id, None)  # what the file holds is no longer known here
            last_step.pop(record.trial_id, None)
            raise
        if recorded is not None:
            recorded.add(record.step)
        last_step[record.trial_id] = (record.step, text)

    def reference_state(self, trial_id: str, step: int) -> ReferenceState | None:
        last = self._own_writes()[1].get(trial_id)
        if last is not None and last[0] == step - 1:  # the text this object wrote, read as a row is
            return self._step_row(trial_id, step - 1, last[1]).to_reference()
        rows = self._query("read the reference state",
                           "SELECT record FROM steps WHERE trial_id = ? AND step = ?", (trial_id, step - 1))
        return self._step_row(trial_id, step - 1, rows[0][0]).to_reference() if rows else None

    def end_trial(self, result: TrialResult) -> None:
        result = storable(result)
        spec = result.spec
        doing = f"end trial {spec.trial_id!r}"
        row = self._serialised(doing, lambda: (spec.trial_id, spec.scenario, spec.environment, spec.arm,
                                               spec.condition, spec.index, spec.seed, result.outcome.value,
                                               result.steps, spec.model_dump_json(), result.model_dump_json()))

        def work(conn: sqlite3.Connection) -> None:
            conn.execute("INSERT OR REPLACE INTO trials VALUES (?, ?, ?, ?, ?, ?, ?, 'finished', ?, ?, ?, ?)", row)

        self._transaction(doing, work)
        began, last_step = self._own_writes()
        began.pop(spec.trial_id, None)
        last_step.pop(spec.trial_id, None)

    def steps(self, trial_id: str) -> list[StepRecord]:
        return list(self.iter_steps(trial_id))

    def iter_steps(self, trial_id: str) -> Iterator[StepRecord]:
        rows = self._query("read steps", "SELECT step, record FROM steps WHERE trial_id = ? ORDER BY step", (trial_id,))
        for step, text in rows:
            yield self._step_row(trial_id, step, text)

    def step_facts(self, trial_ids: Iterable[str]) -> dict[str, StepFacts]:
        """Refusals per rule and attacks per kind from two aggregate queries (milliseconds for
        thousands of trials; the same numbers as counting :meth:`steps`)."""
        facts = {trial_id: StepFacts() for trial_id in trial_ids}
        for query, attribute in ((_REFUSALS, "refusals"), (_ATTACKS, "attacked_by_kind")):
            for trial_id, name, count in self._query("count refusals and attacks", query):
                if trial_id in facts:
                    getattr(facts[trial_id], attribute)[name] += count
        return facts

    def results(self) -> list[TrialResult]:
        """Every finished trial's result, cell by cell (what a resumed ablation skips)."""
        rows = self._query("read trial results", "SELECT trial_id, result FROM trials WHERE status = 'finished' "
                                                 "ORDER BY environment, arm, condition, trial_index")
        seen: set[str] = set()
        results = []
        for trial_id, text in rows:
            if trial_id in seen:
                raise StateStoreError(f"state store {str(self.path)!r}, table trials: trial {trial_id!r} has two rows")
            seen.add(trial_id)
            results.append(self._result_row(trial_id, text))
        return results

    @property
    def persistent(self) -> bool:
        return True

    @property
    def thread_safe(self) -> bool:
        """One connection, every statement under the store's lock; records are serialised before it."""
        return True

    # -- reading a run ------------------------------------------------------------------------

    def trials(self) -> list[dict[str, Any]]:
        """Every trial: id, cell, index, status, outcome and step count, in id order."""
        rows = self._query("list trials", "SELECT trial_id, environment, arm, condition, trial_index, seed, "
                                          "status, outcome, (SELECT COUNT(*) FROM steps s WHERE s.trial_id = "
                                          "t.trial_id) FROM trials t ORDER BY environment, arm, condition, trial_index")
        keys = ("trial_id", "environment", "arm", "condition", "index", "seed", "status", "outcome", "steps")
        return [dict(zip(keys, row)) for row in rows]

    def result(self, trial_id: str) -> TrialResult | None:
        """The stored result of a finished trial (None while it runs or if it never ended)."""
        rows = self._query("read a trial result", "SELECT result FROM trials WHERE trial_id = ?", (trial_id,))
        return self._result_row(trial_id, rows[0][0]) if rows and rows[0][0] else None

    def close(self) -> None:
        if self._conn is not None:
            if self._pid == os.getpid():
                self._conn.close()
            else:
                _INHERITED.append(self._conn)
        self._conn = None
