"""Keep pybullet's C-level chatter out of the terminal.

pybullet writes with C stdio straight to file descriptors 1 and 2 (its build-time banner on
import goes to 2, loader warnings and ``b3Printf`` messages to 1). Python's ``sys.stdout``
redirection cannot catch that, so :func:`silenced` points both descriptors at ``/dev/null``
for the duration of a block and flushes the C library's buffers before restoring them:
without that flush, buffered text would surface later, in the middle of the CLI's output.
Python output written inside the block is lost too, so never log inside one.
"""

from __future__ import annotations

import ctypes
import os
import sys
import threading
from contextlib import contextmanager
from typing import Any, Iterator

_libc: Any = None
_FDS = (1, 2)


def _flush_c_stdio() -> None:
    global _libc
    if _libc is None:
        try:
            _libc = ctypes.CDLL(None)
        except OSError:  # no C library handle (unusual platforms): nothing to flush
            _libc = False
    if _libc:
        _libc.fflush(None)


_lock = threading.Lock()
_depth = 0
_saved: list[int] = []


@contextmanager
def silenced() -> Iterator[None]:
    """Send everything written to file descriptors 1 and 2 (stdout and stderr) inside the block to
    ``/dev/null``.

    Thread-safe and nestable: the descriptors are process-wide, so the first block to enter
    redirects them and the last to leave restores them (two threads each saving and restoring on
    their own would leave ``/dev/null`` behind when their blocks overlap).
    """
    global _depth
    with _lock:
        if _depth == 0:
            _redirect()
        _depth += 1
    try:
        yield
    finally:
        with _lock:
            _depth -= 1
            if _depth == 0:
                _restore()


def _redirect() -> None:
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError):
            pass
    _flush_c_stdio()
    _saved[:] = [os.dup(fd) for fd in _FDS]
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
    except OSError:  # no descriptor left: nothing is silenced, nothing leaks
        for copy in _saved:
            os.close(copy)
        _saved.clear()
        raise
    try:
        for fd in _FDS:
            os.dup2(devnull, fd)
    finally:
        os.close(devnull)


def _restore() -> None:
    if not _saved:  # the redirect failed: nothing to put back
        return
    _flush_c_stdio()
    for fd, copy in zip(_FDS, _saved):
        os.dup2(copy, fd)
        os.close(copy)
    _saved.clear()


def import_pybullet() -> tuple[Any, str]:
    """``(pybullet, pybullet_data path)``, imported without the build-time banner."""
    with silenced():
        import pybullet
        import pybullet_data
    return pybullet, pybullet_data.getDataPath()
