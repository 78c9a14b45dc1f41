"""Reading a run folder and writing the site without trusting either.

A run folder may come from someone else: a figure or a trajectory there may be a symlink to a file
of yours, a device or a FIFO, and the site folder itself (or a folder in it) may have been planted
as a symlink to somewhere you care about. So: files are read from a run folder only when they are
regular files reached with no symlink anywhere below the run folder (a symlinked ``figures/`` or
``trajectories/`` as much as a symlinked picture), up to a size, and as PNG when a picture is expected
(:func:`read_run_file`), and the page says what was left out and why; every file of the site is
written aside and renamed into place -- the rename replaces a symlink rather than writing through it
-- and only where it resolves inside the site (:class:`Site`); a site folder that is a symlink, or an
existing folder that is not a site of ours, is refused.
"""

from __future__ import annotations

import os
import re
import tempfile
from pathlib import Path

from ..errors import SafeEmbodAIError
from ..runs.files import UnreadableFile, read_untrusted

PNG = b"\x89PNG\r\n\x1a\n"
MAX_PICTURE_BYTES = 20_000_000
MANIFEST = "manifest.json"
_SAFE_NAME = re.compile(r"[^A-Za-z0-9_.-]")


def safe_name(text: str) -> str:
    """``text`` as one file name: letters, digits, ``_``, ``.``, ``-``; anything else as ``-``."""
    name = _SAFE_NAME.sub("-", text)[:120].lstrip(".")
    return name or "unnamed"


def read_run_file(path: Path, max_bytes: int = MAX_PICTURE_BYTES, png: bool = False, folder: Path | None = None,
                  left_out: list[str] | None = None) -> bytes | None:
    """The bytes of ``path`` when it is a regular file of at most ``max_bytes`` (and a PNG, with
    ``png``), reached from the run folder ``folder`` with no symlink anywhere below it (default: its own
    folder); None otherwise (:func:`~safeembodai_core.runs.files.open_inside`). ``left_out``: where to say
    why a file that is there was refused (``figures/x.png: a symlink (not followed)``), for the page."""
    try:
        data = read_untrusted(Path(path), max_bytes, folder)
    except FileNotFoundError:
        return None
    except (OSError, SafeEmbodAIError) as error:
        _note(left_out, path, folder, error.reason if isinstance(error, UnreadableFile) else str(error))
        return None
    if png and not data.startswith(PNG):
        _note(left_out, path, folder, "not a PNG")
        return None
    return data


def _note(left_out: list[str] | None, path: Path, folder: Path | None, why: str) -> None:
    if left_out is not None:
        shown = Path(path).relative_to(folder) if folder is not None and Path(path).is_relative_to(folder) else path
        left_out.append(f"{shown.as_posix()}: {why}")


class Site:
    """The site folder: created or reused (when it is ours), written file by file (module docstring)."""

    def __init__(self, out: Path, checked: bool = False) -> None:
        """``checked``: the build that started this process checked ``out`` (a helper process's site,
        written before its manifest is)."""
        if checked:
            self.out, self.root = out, Path(os.path.realpath(out))
            return
        if out.is_symlink():
            raise SafeEmbodAIError(f"{out} is a symlink: give a real folder as --out")
        if out.exists():
            if not out.is_dir():
                raise SafeEmbodAIError(f"{out} is not a folder: give a folder as --out")
            if any(out.iterdir()) and not (out / MANIFEST).is_file():
                raise SafeEmbodAIError(f"{out} holds files but no site of ours ({MANIFEST}): give a new or empty --out")
        out.mkdir(parents=True, exist_ok=True)
        self.out = out
        self.root = Path(os.path.realpath(out))

    def path(self, relative: str) -> Path:
        """Where ``relative`` goes, its folders made, refused when it would resolve outside the site."""
        target = self.out / relative
        target.parent.mkdir(parents=True, exist_ok=True)
        parent = Path(os.path.realpath(target.parent))
        if parent != self.root and self.root not in parent.parents:
            raise SafeEmbodAIError(f"{target} would be written outside the site {self.out} (a symlink in it?)")
        return target

    def write(self, relative: str, data: str | bytes) -> Path:
        """Write ``relative`` whole or not at all; a symlink at its place is replaced, not followed."""
        target = self.path(relative)
        fd, partial = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".partial", dir=target.parent)
        try:
            with os.fdopen(fd, "wb") as handle:
                handle.write(data.encode("utf-8") if isinstance(data, str) else data)
            os.replace(partial, target)
        except BaseException:
            try:
                os.unlink(partial)
            except OSError:
                pass
            raise
        return target

    def read(self, relative: str) -> str | None:
        """A text file of the site (the manifest), when it is a regular file of ours."""
        data = read_run_file(self.out / relative, max_bytes=50_000_000)
        return data.decode("utf-8", errors="replace") if data is not None else None
