"""How the processes of a run end together: workers die with their coordinator, and a coordinator
stops cleanly on SIGINT or SIGTERM.

A worker whose coordinator is gone (``kill -9``, out of memory, a crash) must not live on: it would
sit blocked on the call queue, holding the workers lock that keeps a resume out. A worker spawned
by its coordinator asks Linux to kill it when its parent dies (``PR_SET_PDEATHSIG``) and, on every
platform, runs a daemon thread that ends the process at once with ``os._exit``, whatever the main
thread is doing, when its coordinator is gone: when the *lifeline* -- the reading end of a pipe
whose only writing end the coordinator holds -- reads end-of-file, or, without one, when its parent
pid changes. A worker forked from the fork server (:mod:`.warm_start`) has the server for parent,
not the coordinator: the lifeline is how it knows. A trial cut off that way is not recorded as
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


def orphaned(coordinator: int, lifeline: Any = None) -> bool:
    """Is the coordinator gone? With a ``lifeline`` (a ``multiprocessing`` connection the coordinator
    never writes to): it reads end-of-file; without one: this process's parent is no longer ``coordinator``."""
    if lifeline is None:
        return os.getppid() != coordinator
    try:
        return lifeline.poll(0)
    except (OSError, EOFError):
        return True


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


def _watch(coordinator: int, lifeline: Any) -> None:
    if lifeline is not None:
        try:
            lifeline.poll(None)  # returns at end-of-file: the coordinator's end closed with it
        except (OSError, EOFError):
            pass
        os._exit(1)
    while not orphaned(coordinator):
        time.sleep(POLL_S)
    os._exit(1)


def bind_to_coordinator(coordinator: int, lifeline: Any = None) -> None:
    """In a worker: end this process as soon as ``coordinator`` is gone (its ``lifeline`` reads
    end-of-file; without one: its parent, which must be the coordinator, is gone)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if os.getppid() == coordinator:  # a worker forked from the fork server has the server for parent
        _die_with_parent()
    if orphaned(coordinator, lifeline):  # it died before the line above took effect
        os._exit(1)
    threading.Thread(target=_watch, args=(coordinator, lifeline), name="coordinator-watchdog", daemon=True).start()


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
