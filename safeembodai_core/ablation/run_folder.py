"""A run folder: the scenario it ran (fingerprinted), its results store, pictures and reports.

``scenario.json`` holds the validated scenario and its SHA-256 fingerprint. Resuming compares the
scenario given now with it and refuses any difference, naming the keys that changed, because
mixing trials of two different scenarios would make every metric meaningless.
"""

from __future__ import annotations

import hashlib
import json
import os
import time
from pathlib import Path
from typing import Any

from ..errors import SafeEmbodAIError
from ..scenario import Scenario

SCENARIO_FILE = "scenario.json"
COORDINATOR_LOCK = ".coordinator.lock"
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
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write the run folder {self.path}: {error}") from None

    def recorded_scenario(self) -> dict[str, Any]:
        target = self.path / SCENARIO_FILE
        try:
            return json.loads(target.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise SafeEmbodAIError(f"{self.path} is not a run folder (no {SCENARIO_FILE})") from None
        except (OSError, json.JSONDecodeError) as error:
            raise SafeEmbodAIError(f"{target} is unreadable: {error}") from None

    def check_same(self, scenario: Scenario) -> None:
        """Refuse to resume with a scenario that differs from the one the run started with."""
        recorded = self.recorded_scenario()
        if recorded.get("fingerprint") == fingerprint(scenario):
            return
        changed = _changed_keys(recorded.get("scenario", {}), scenario.model_dump(mode="json"))
        raise SafeEmbodAIError(
            f"the scenario differs from the one {self.path} was started with (changed: {', '.join(changed) or 'unknown'}); "
            "resume with the same scenario and overrides, or start a new run"
        )

    def scenario(self) -> Scenario:
        return Scenario.model_validate(self.recorded_scenario()["scenario"])


def _flock(path: Path, exclusive: bool, wait: bool) -> int | None:
    """Open ``path`` and lock it; the descriptor, or None when another process holds a conflicting lock.

    Advisory POSIX locks: they vanish with the process that holds them, ``kill -9`` included.
    On platforms without ``fcntl`` no locking is done (and every call succeeds).
    """
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        return -1
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    mode = (fcntl.LOCK_EX if exclusive else fcntl.LOCK_SH) | (0 if wait else fcntl.LOCK_NB)
    try:
        fcntl.flock(fd, mode)
    except BlockingIOError:
        os.close(fd)
        return None
    return fd


class RunLock:
    """Keeps two coordinators, or a coordinator and orphaned workers, off the same run folder.

    The coordinator holds ``.coordinator.lock`` exclusively for the whole run; every local worker
    holds ``.workers.lock`` shared for its lifetime. A new coordinator (a resume) therefore refuses
    to start while an earlier one is alive, and while workers of a killed coordinator are still
    finishing a trial, so no trial can be run by two processes at once.
    """

    def __init__(self, folder: Path) -> None:
        self.folder = folder
        self.fd: int | None = None

    def acquire(self) -> None:
        fd = _flock(self.folder / COORDINATOR_LOCK, exclusive=True, wait=False)
        if fd is None:
            raise SafeEmbodAIError(f"another 'safeembodai ablate' is running on {self.folder}; wait for it to end")
        workers = _flock(self.folder / WORKERS_LOCK, exclusive=True, wait=False)
        if workers is None:
            os.close(fd)
            raise SafeEmbodAIError(f"worker processes of an earlier run of {self.folder} are still finishing trials; "
                                   "resume again once they have exited")
        if workers >= 0:
            os.close(workers)
        self.fd = fd

    def release(self) -> None:
        if self.fd is not None and self.fd >= 0:
            os.close(self.fd)
        self.fd = None


def hold_worker_lock(folder: str | Path) -> int | None:
    """Called in each local worker: hold the shared workers lock until the process exits."""
    return _flock(Path(folder) / WORKERS_LOCK, exclusive=False, wait=True)
