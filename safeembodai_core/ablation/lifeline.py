"""How the processes of a run end together: workers die with their coordinator, and a coordinator
stops cleanly on SIGINT or SIGTERM.

A worker whose coordinator is gone (``kill -9``, out of memory, a crash) must not live on: it would
sit blocked on the call queue, holding the workers lock that keeps a resume out. Each worker asks
Linux to kill it when its parent dies (``PR_SET_PDEATHSIG``) and, on every platform, runs a daemon
thread that checks its parent pid a few times a second and ends the process at once with
``os._exit``, whatever the main thread is doing. A trial cut off that way is not recorded as
finished (its steps are dropped when it runs again); a trial whose result was stored just before
counts as done, so resuming neither repeats nor changes it.

Workers ignore SIGINT: a Ctrl-C in the terminal reaches the whole process group, and it is the
coordinator that decides how its workers stop (it kills them; see ``ProcessExecutor.abort``).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from types import FrameType
from typing import Any

PR_SET_PDEATHSIG = 1
POLL_S = 0.2


def orphaned(coordinator: int) -> bool:
    return os.getppid() != coordinator


def _die_with_parent() -> None:
    """Linux only: the kernel sends SIGKILL to this process when its parent exits."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
    except (OSError, AttributeError):  # no libc prctl: the watchdog thread still covers it
        pass


def _watch(coordinator: int) -> None:
    while not orphaned(coordinator):
        time.sleep(POLL_S)
    os._exit(1)


def bind_to_coordinator(coordinator: int) -> None:
    """In a worker: end this process as soon as ``coordinator`` (its parent) is gone."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _die_with_parent()
    if orphaned(coordinator):  # it died before the line above took effect
        os._exit(1)
    threading.Thread(target=_watch, args=(coordinator,), name="coordinator-watchdog", daemon=True).start()


class StopSignals:
    """In the coordinator: SIGINT and SIGTERM both raise :class:`KeyboardInterrupt` once, for a clean stop.

    ``signum`` tells which arrived (None if neither); the conventional exit code is ``128 + signum``.
    Later signals during the stop are noted but do not interrupt the cleanup.
    """

    def __init__(self) -> None:
        self.signum: int | None = None
        self._previous: dict[int, Any] = {}

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if self.signum is None:
            self.signum = signum
            raise KeyboardInterrupt(signal.Signals(signum).name)

    @property
    def exit_code(self) -> int:
        return 128 + (self.signum or signal.SIGINT)

    def __enter__(self) -> "StopSignals":
        if threading.current_thread() is threading.main_thread():
            for signum in (signal.SIGINT, signal.SIGTERM):
                self._previous[signum] = signal.signal(signum, self._handle)
        return self

    def __exit__(self, *exc: object) -> None:
        for signum, previous in self._previous.items():
            signal.signal(signum, previous)
        self._previous.clear()
