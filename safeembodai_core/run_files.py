"""Names of what a run folder holds, for the modules that write them and those that read them.

Its own module so that the run folder (:mod:`safeembodai_core.ablation.run_folder`, which
writes the bag marker) and the runner (:mod:`safeembodai_core.runner`, which reads it) need not
import each other.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path

from .errors import SafeEmbodAIError

#: Where a run folder keeps the Rerun recordings of its trials (``ablate --rerun``, or exported there).
RECORDINGS_DIR = "recordings"
#: A run folder whose ``recordings/`` holds this file writes a Rerun recording per trial as it ends
#: (its text: ``rrd``); ``ablate --rerun`` writes it.
RECORD_FILE = "record"
#: What a Rerun recording starts with, and the largest one a run folder's reader accepts.
RRD_MAGIC = b"RRF2"
MAX_RECORDING_BYTES = 64 * 1024 * 1024
#: A run folder whose ``bags/`` holds this file records a ROS 2 bag per trial as it ends (its text:
#: the storage, ``mcap`` or ``sqlite3``); ``ablate --bags`` writes it.
BAGS_DIR = "bags"
BAG_STORAGE_FILE = "storage"


def trial_file_name(trial_id: str) -> str:
    """A trial's id as one file name (``MO/safeembodai/attack/3`` -> ``MO__safeembodai__attack__3``): its
    picture, its bag and its exported bag are named so."""
    return trial_id.replace("/", "__")


def read_regular_file(path: str | Path, max_bytes: int) -> bytes | None:
    """The bytes of ``path`` when it is a regular file (no symlink followed) of at most ``max_bytes``;
    None otherwise (absent, a symlink, a FIFO, a device, a folder, too large). Never blocks on a FIFO.
    The one reader of files that came from elsewhere: a run folder's pictures, a response cache."""
    try:
        return read_untrusted(Path(path), max_bytes)
    except (OSError, SafeEmbodAIError):
        return None


def read_run_text(path: str | Path, max_bytes: int) -> str:
    """The UTF-8 text of a run folder's file; FileNotFoundError when it is absent, and an error naming it
    when it is a symlink, not a regular file, larger than ``max_bytes`` or not UTF-8."""
    path = Path(path)
    data = read_untrusted(path, max_bytes)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise SafeEmbodAIError(f"{path} is unreadable: not UTF-8 ({error.reason} at byte {error.start})") from None


def read_untrusted(path: Path, max_bytes: int) -> bytes:
    """:func:`read_run_text`'s bytes (see there)."""
    flags = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
    try:
        fd = os.open(path, flags)
    except FileNotFoundError:
        raise
    except OSError as error:
        why = "a symlink (not followed)" if error.errno == errno.ELOOP else (error.strerror or str(error))
        raise SafeEmbodAIError(f"{path} is unreadable: {why}") from None
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise SafeEmbodAIError(f"{path} is unreadable: not a regular file")
        if info.st_size > max_bytes:
            raise SafeEmbodAIError(f"{path} is unreadable: larger than {max_bytes:,} bytes")
        with os.fdopen(fd, "rb", closefd=False) as handle:
            data = handle.read(max_bytes + 1)
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise SafeEmbodAIError(f"{path} is unreadable: larger than {max_bytes:,} bytes")
    return data
