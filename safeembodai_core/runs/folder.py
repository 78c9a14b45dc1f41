"""A run folder: the scenario it ran (fingerprinted), its results store, pictures and reports.

``scenario.json`` holds the validated scenario and its SHA-256 fingerprint. Resuming compares the
scenario given now with it and refuses any difference, naming the keys that changed, because
mixing trials of two different scenarios would make every metric meaningless.

``finished.jsonl`` is the run's own ledger: the id of every trial whose result the coordinator has
seen in the store (outcome ``error`` aside, as those are run again), appended only after the store
holds it. The ledger is never ahead of the store, so a store that holds fewer of those trials was
deleted, emptied or replaced, and resuming from it would silently run them again.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path
from typing import Any

from ..errors import SafeEmbodAIError
from .files import read_run_text
from ..scenario import Scenario

SCENARIO_FILE = "scenario.json"
LEDGER_FILE = "finished.jsonl"
COORDINATOR_LOCK = ".coordinator.lock"
#: The largest scenario.json and finished.jsonl read back (far beyond a real run's).
MAX_SCENARIO_BYTES = 16_000_000
MAX_LEDGER_BYTES = 256_000_000
WORKERS_LOCK = ".workers.lock"


def fingerprint(scenario: Scenario) -> str:
    canonical = json.dumps(scenario.model_dump(mode="json"), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(canonical.encode()).hexdigest()


def _changed_keys(old: Any, new: Any, prefix: str = "") -> list[str]:
    if isinstance(old, dict) and isinstance(new, dict):
        keys = sorted(set(old) | set(new))
        return [k for key in keys for k in _changed_keys(old.get(key), new.get(key), f"{prefix}{key}.")]
    return [] if old == new else [prefix.rstrip(".") or "(root)"]


class RunFolder:
    """The folder of one ablation run."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    @classmethod
    def create(cls, root: str | Path, scenario: Scenario) -> "RunFolder":
        stamp = time.strftime("%Y%m%d-%H%M%S")
        path = Path(root) / f"{scenario.name}-{stamp}"
        suffix = 1
        while path.exists():
            suffix += 1
            path = Path(root) / f"{scenario.name}-{stamp}-{suffix}"
        return cls(path)

    def start(self, scenario: Scenario) -> None:
        """Create the folder and record the scenario (new runs only)."""
        try:
            self.path.mkdir(parents=True, exist_ok=True)
            target = self.path / SCENARIO_FILE
            if target.exists():
                raise SafeEmbodAIError(f"{self.path} already holds a run; use --resume {self.path} to finish it")
            record = {"fingerprint": fingerprint(scenario), "scenario": scenario.model_dump(mode="json")}
            target.write_text(json.dumps(record, indent=2), encoding="utf-8")
            self.ledger_path.write_text("", encoding="utf-8")
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write the run folder {self.path}: {error}") from None

    def recorded_scenario(self) -> dict[str, Any]:
        target = self.path / SCENARIO_FILE
        try:
            record = json.loads(read_run_text(target, MAX_SCENARIO_BYTES))
        except FileNotFoundError:
            raise SafeEmbodAIError(f"{self.path} is not a run folder (no {SCENARIO_FILE})") from None
        except (OSError, json.JSONDecodeError, RecursionError) as error:
            raise SafeEmbodAIError(f"{target} is unreadable: {error}") from None
        if not (isinstance(record, dict) and isinstance(record.get("fingerprint"), str)
                and isinstance(record.get("scenario"), dict)):
            raise SafeEmbodAIError(f"{target} is not a recorded scenario (expected the keys 'fingerprint' and "
                                   "'scenario' that 'safeembodai ablate' writes)")
        return record

    def check_same(self, scenario: Scenario) -> None:
        """Refuse to resume with a scenario that differs from the one the run started with."""
        recorded = self.recorded_scenario()
        if recorded.get("fingerprint") == fingerprint(scenario):
            return
        changed = _changed_keys(recorded.get("scenario", {}), scenario.model_dump(mode="json"))
        raise SafeEmbodAIError(
            f"the scenario differs from the one {self.path} was started with "
            f"(changed: {', '.join(changed) or 'unknown'}); "
            "resume with the same scenario and overrides, or start a new run"
        )

    def scenario(self) -> Scenario:
        from pydantic import ValidationError

        try:
            return Scenario.model_validate(self.recorded_scenario()["scenario"])
        except ValidationError as error:
            first = error.errors()[0]
            where = ".".join(str(part) for part in first["loc"]) or "(root)"
            more = f" (and {error.error_count() - 1} more)" if error.error_count() > 1 else ""
            raise SafeEmbodAIError(f"{self.path / SCENARIO_FILE} is not a recorded scenario: "
                                   f"{where}: {first['msg']}{more}") from None

    # -- the ledger of finished trials -------------------------------------------------------

    @property
    def ledger_path(self) -> Path:
        return self.path / LEDGER_FILE

    def finished(self) -> list[str] | None:
        """Trial ids in the ledger, oldest first; None when the run has no ledger (older versions).

        A line cut short by a kill in the middle of an append is ignored: its trial is in the store.
        """
        try:
            text = read_run_text(self.ledger_path, MAX_LEDGER_BYTES)
        except FileNotFoundError:
            return None
        except OSError as error:
            raise SafeEmbodAIError(f"{self.ledger_path} is unreadable: {error}") from None
        ids = []
        for line in text.splitlines(keepends=True):
            try:
                trial_id = json.loads(line) if line.endswith("\n") else None
            except json.JSONDecodeError:
                trial_id = None
            if isinstance(trial_id, str):
                ids.append(trial_id)
        return ids

    def note_finished(self, trial_ids: list[str]) -> None:
        """Append ``trial_ids`` to the ledger (call only once the store holds their results)."""
        lines = "".join(json.dumps(trial_id) + "\n" for trial_id in trial_ids).encode("utf-8")
        try:
            with self.ledger_path.open("a+b") as ledger:
                if ledger.seek(0, os.SEEK_END):
                    ledger.seek(-1, os.SEEK_END)
                    if ledger.read(1) != b"\n":  # a line cut short by a kill: never glue the next one to it
                        lines = b"\n" + lines
                ledger.write(lines)
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write {self.ledger_path}: {error.strerror or error}") from None


_HELD: set[int] = set()  # lock descriptors of this process, closed in any child it forks


def _forget_locks_in_child() -> None:
    """A forked child shares its parent's locks through inherited descriptors: drop them, so a
    lock lives exactly as long as the process that took it (and never in, say, a helper the
    worker forked that outlives it)."""
    for fd in _HELD:
        try:
            os.close(fd)
        except OSError:
            pass
    _HELD.clear()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_locks_in_child)


def _flock(path: Path, exclusive: bool, wait: bool) -> int | None:
    """Open ``path`` and lock it; the descriptor, or None when another process holds a conflicting lock.

    Advisory POSIX locks: they vanish with the process that holds them, ``kill -9`` included.
    The descriptor is not inherited across ``exec`` (Python's default) nor kept by forked
    children (see :func:`_forget_locks_in_child`). On platforms without ``fcntl`` no locking is
    done (and every call succeeds).

    A lock counts only on the file that ``path`` names once it is held: its holder may remove
    the file (:func:`_remove_held`), and a process that opened it before and got the lock after
    that holds a lock on a file nobody else can open, so it tries again on the one at ``path``.
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return -1
    mode = (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | (0 if wait else fcntl.LOCK_NB)
    while True:
        try:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as error:
            raise SafeEmbodAIError(f"cannot open the lock file {path}: {error.strerror or error} "
                                   "(a run folder must be writable to run or report it)") from None
        try:
            fcntl.flock(fd, mode)
        except BlockingIOError:
            os.close(fd)
            return None
        if _names(path, fd):
            _HELD.add(fd)
            return fd
        os.close(fd)  # removed by its holder while this process waited: lock the file at path now


def _names(path: Path, fd: int) -> bool:
    """Whether ``path`` still names the file open as ``fd`` (an open file's inode is never reused)."""
    try:
        named = os.stat(path)
    except FileNotFoundError:
        return False
    held = os.fstat(fd)
    return (named.st_dev, named.st_ino) == (held.st_dev, held.st_ino)


def _remove_held(path: Path, fd: int) -> None:
    """Remove the lock file ``path`` while this process holds it exclusively as ``fd``; the caller
    unlocks ``fd`` afterwards.

    Only then is it safe: no other process holds a lock on it, and one that opened it and waits
    for it finds, once it has the lock, that ``path`` no longer names it (:func:`_flock`). Removing
    it after the unlock instead could delete a file another process has just locked. A file that
    cannot be removed (a folder made read-only meanwhile) stays: it holds nothing.
    """
    if _names(path, fd):
        try:
            os.unlink(path)
        except OSError:
            pass


def _unlock(fd: int) -> None:
    _HELD.discard(fd)
    os.close(fd)


def lock_holders(path: Path) -> list[int]:
    """Pids holding a lock on ``path`` (from ``/proc/locks``; empty where that is unavailable)."""
    try:
        info = os.stat(path)
        lines = Path("/proc/locks").read_text().splitlines()
    except OSError:
        return []
    wanted = f"{os.major(info.st_dev):02x}:{os.minor(info.st_dev):02x}:{info.st_ino}"
    pids = {int(fields[4]) for fields in (line.split() for line in lines)
            if len(fields) > 5 and fields[5] == wanted and fields[4].isdigit()}
    return sorted(pids)


class RunInProgress(SafeEmbodAIError):
    """Another coordinator (or workers of a killed one) still works on the run folder."""


class RunLock:
    """Keeps two coordinators, or a coordinator and orphaned workers, off the same run folder.

    The coordinator holds ``.coordinator.lock`` exclusively for the whole run; every local worker
    holds ``.workers.lock`` shared for its lifetime. A new coordinator (a resume) therefore refuses
    to start while an earlier one is alive, and while workers of a killed coordinator are still
    alive, so no trial can be run by two processes at once. Workers exit within a fraction of a
    second of their coordinator's death (see ``lifeline.py``): ``acquire`` waits ``wait_s`` for them.

    ``release`` removes both files, so a finished run folder holds none: each is removed while
    this process holds it exclusively (the workers lock only when no worker holds it any more),
    never after letting go (:func:`_remove_held`). A killed coordinator leaves them; they hold
    nothing then, and the next ``acquire`` on the folder uses them.
    """

    def __init__(self, folder: Path, wait_s: float = 3.0) -> None:
        self.folder = folder
        self.wait_s = wait_s
        self.fd: int | None = None

    def acquire(self) -> None:
        fd = _flock(self.folder / COORDINATOR_LOCK, exclusive=True, wait=False)
        if fd is None:
            raise RunInProgress(f"another 'safeembodai ablate' is running on {self.folder}; wait for it to end")
        deadline = time.monotonic() + self.wait_s
        while (workers := _flock(self.folder / WORKERS_LOCK, exclusive=True, wait=False)) is None:
            if time.monotonic() >= deadline:
                _unlock(fd)
                pids = lock_holders(self.folder / WORKERS_LOCK)
                named = f" (pid {', '.join(map(str, pids))})" if pids else ""
                raise RunInProgress(f"worker processes of an earlier run of {self.folder} are still alive{named}; "
                                    "try again once they have exited")
            time.sleep(0.1)
        if workers >= 0:
            _unlock(workers)
        self.fd = fd

    def release(self) -> None:
        """Let go of the run folder and remove its lock files (see the class docstring)."""
        if self.fd is not None and self.fd >= 0:
            path = self.folder / WORKERS_LOCK
            workers = _flock(path, exclusive=True, wait=False) if path.exists() else None
            if workers is not None and workers >= 0:  # no worker holds it: this process does now
                _remove_held(path, workers)
                _unlock(workers)
            _remove_held(self.folder / COORDINATOR_LOCK, self.fd)
            _unlock(self.fd)
        self.fd = None


def hold_worker_lock(folder: str | Path) -> int | None:
    """Called in each local worker: hold the shared workers lock until the process exits."""
    return _flock(Path(folder) / WORKERS_LOCK, exclusive=False, wait=True)
