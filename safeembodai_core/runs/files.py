"""Names of what a run folder holds, for the modules that write them and those that read them.

Its own module so that the run folder (:mod:`safeembodai_core.runs.folder`, which
writes the bag marker) and the runner (:mod:`safeembodai_core.runs.runner`, which reads it) need not
import each other. It also holds the one way a file of a folder from elsewhere is opened
(:func:`open_inside`: a regular file, reached from the folder with no symlink anywhere below it,
never blocking) and the bounded readers built on it.
"""

from __future__ import annotations

import errno
import os
import stat
from pathlib import Path
from typing import Callable

from ..errors import SafeEmbodAIError

#: Where a run folder keeps the report's figures (``report.md`` shows them, ``view`` copies them).
FIGURES_DIR = "figures"
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


def read_regular_file(path: str | Path, max_bytes: int, folder: str | Path | None = None) -> bytes | None:
    """The bytes of ``path`` when it is a regular file of at most ``max_bytes``; None otherwise (absent,
    a symlink, a FIFO, a device, a folder, too large). Never blocks on a FIFO. ``folder``: the folder from
    elsewhere that ``path`` lies in, none of whose names below it may be a symlink (:func:`open_inside`;
    default: ``path``'s own folder, so its own name only). The one reader of files that came from
    elsewhere: a run folder's pictures, a response cache."""
    try:
        return read_untrusted(Path(path), max_bytes, folder)
    except (OSError, SafeEmbodAIError):
        return None


def read_run_text(path: str | Path, max_bytes: int, folder: str | Path | None = None) -> str:
    """The UTF-8 text of a run folder's file; FileNotFoundError when it is absent, and an error naming it
    when it is reached through a symlink below ``folder`` (:func:`open_inside`), is not a regular file, is
    larger than ``max_bytes`` or is not UTF-8."""
    path = Path(path)
    data = read_untrusted(path, max_bytes, folder)
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as error:
        raise SafeEmbodAIError(f"{path} is unreadable: not UTF-8 ({error.reason} at byte {error.start})") from None


def read_untrusted(path: Path, max_bytes: int, folder: str | Path | None = None) -> bytes:
    """:func:`read_run_text`'s bytes (see there)."""
    fd, info = open_inside(path.parent if folder is None else Path(folder), path)
    try:
        if info.st_size > max_bytes:
            raise UnreadableFile(path, f"larger than {max_bytes:,} bytes")
        with os.fdopen(fd, "rb", closefd=False) as handle:
            data = handle.read(max_bytes + 1)
    finally:
        os.close(fd)
    if len(data) > max_bytes:
        raise UnreadableFile(path, f"larger than {max_bytes:,} bytes")
    return data


class UnreadableFile(SafeEmbodAIError):
    """A file of a folder from elsewhere that is there but refused, and why (``reason``)."""

    def __init__(self, path: Path, reason: str) -> None:
        super().__init__(f"{path} is unreadable: {reason}")
        self.path, self.reason = path, reason


_FLAGS = os.O_RDONLY | getattr(os, "O_NOFOLLOW", 0) | getattr(os, "O_NONBLOCK", 0)
_IN_FOLDER = os.open in os.supports_dir_fd and hasattr(os, "O_DIRECTORY") and hasattr(os, "O_NOFOLLOW")


def _below(folder: Path, path: Path) -> list[str]:
    """The names from ``folder`` down to ``path``; an error when ``path`` is not below it (``..`` included)."""
    try:
        parts = path.relative_to(folder).parts
    except ValueError:
        raise UnreadableFile(path, f"not inside {folder}") from None
    if not parts or any(part in ("", ".", "..") for part in parts):
        raise UnreadableFile(path, f"not a file inside {folder}")
    return list(parts)


def _open_folder(folder: Path, names: list[str], path: Path) -> int:
    """A descriptor of the folder ``folder/names...``, each name opened from the one before without
    following a symlink."""
    directory = os.O_RDONLY | os.O_DIRECTORY | getattr(os, "O_NONBLOCK", 0)
    fd = _open_file(path, lambda: os.open(folder, directory))  # the folder itself: the caller's choice
    try:
        for index, name in enumerate(names):
            try:
                inner = os.open(name, directory | os.O_NOFOLLOW, dir_fd=fd)
            except FileNotFoundError as error:
                raise FileNotFoundError(error.errno, error.strerror, str(path)) from None
            except OSError as error:
                shown = "/".join(names[:index + 1])
                why = (f"{shown} is a symlink (not followed)" if os.path.islink(os.path.join(folder, shown)) else
                       f"{shown} is not a folder" if error.errno == errno.ENOTDIR else error.strerror or str(error))
                raise UnreadableFile(path, why) from None
            os.close(fd)
            fd = inner
    except BaseException:
        os.close(fd)
        raise
    return fd


def open_inside(folder: Path, path: Path) -> tuple[int, os.stat_result]:
    """A read-only, non-blocking descriptor of the regular file ``path`` inside ``folder``, and its
    status: every name below ``folder`` is opened from the one before it without following a symlink
    (so no symlink anywhere below the folder -- a folder or the file itself -- and no ``..``), and what
    was opened is what is checked and read. FileNotFoundError when it is absent; :class:`UnreadableFile`
    saying why otherwise (a symlink, a FIFO, a device, a folder, outside ``folder``). The one check of
    "a file of this folder" for every reader of a folder from elsewhere: a run folder's files, the
    response cache's, the site ``view --serve`` serves."""
    names = _below(Path(folder), path)
    if _IN_FOLDER:
        parent = _open_folder(Path(folder), names[:-1], path)
        try:
            fd = _open_file(path, lambda: os.open(names[-1], _FLAGS, dir_fd=parent))
        finally:
            os.close(parent)
    else:  # no openat here (not POSIX): each folder on the way checked, then the path opened
        _no_symlink_on_the_way(Path(folder), names[:-1], path)
        fd = _open_file(path, lambda: os.open(path, _FLAGS))
    try:
        info = os.fstat(fd)
        if not stat.S_ISREG(info.st_mode):
            raise UnreadableFile(path, "a folder" if stat.S_ISDIR(info.st_mode) else "not a regular file")
    except BaseException:
        os.close(fd)
        raise
    return fd, info


def _no_symlink_on_the_way(folder: Path, names: list[str], path: Path) -> None:
    """Without openat: each folder on the way checked in turn (a swap after the check is not seen)."""
    for index in range(len(names)):
        if Path(folder, *names[:index + 1]).is_symlink():
            raise UnreadableFile(path, f"{'/'.join(names[:index + 1])} is a symlink (not followed)")


def _open_file(path: Path, opener: Callable[[], int]) -> int:
    try:
        return opener()
    except FileNotFoundError as error:  # named by the whole path, not the name opened from its folder
        raise FileNotFoundError(error.errno, error.strerror, str(path)) from None
    except OSError as error:
        why = "a symlink (not followed)" if error.errno == errno.ELOOP else (error.strerror or str(error))
        raise UnreadableFile(path, why) from None


def folder_names(folder: Path, inner: Path) -> list[str]:
    """The names in the folder ``inner`` below ``folder`` (reached as :func:`open_inside` reaches a
    file: no symlink below ``folder``); FileNotFoundError when it is absent, :class:`UnreadableFile`
    when it is reached through a symlink or is no folder."""
    names = _below(Path(folder), inner)
    if not _IN_FOLDER:
        _no_symlink_on_the_way(Path(folder), names, inner)
        return sorted(os.listdir(inner))
    fd = _open_folder(Path(folder), names, inner)
    try:
        return sorted(os.listdir(fd))
    finally:
        os.close(fd)
