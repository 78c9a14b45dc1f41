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
from contextlib import contextmanager
from typing import Any, Iterator

_libc: Any = None


def _flush_c_stdio() -> None:
    global _libc
    if _libc is None:
        try:
            _libc = ctypes.CDLL(None)
        except OSError:  # no C library handle (unusual platforms): nothing to flush
            _libc = False
    if _libc:
        _libc.fflush(None)


@contextmanager
def silenced(fds: tuple[int, ...] = (1, 2)) -> Iterator[None]:
    """Send everything written to ``fds`` (stdout and stderr) inside the block to ``/dev/null``."""
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (AttributeError, ValueError):
            pass
    _flush_c_stdio()
    saved = [os.dup(fd) for fd in fds]
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        for fd in fds:
            os.dup2(devnull, fd)
        yield
    finally:
        _flush_c_stdio()
        for fd, copy in zip(fds, saved):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(devnull)


def import_pybullet() -> tuple[Any, str]:
    """``(pybullet, pybullet_data path)``, imported without the build-time banner."""
    with silenced():
        import pybullet
        import pybullet_data
    return pybullet, pybullet_data.getDataPath()
