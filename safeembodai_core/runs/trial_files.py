"""Where a trial's files go: its picture, its ROS 2 bag and its Rerun recording.

:class:`~safeembodai_core.runs.artefacts.TrialArtefacts` hands them to a :class:`TrialFiles` and knows
nothing more of where they end up. :class:`FolderFiles` writes them into the run folder, each
whole or not at all; on a Ray node the relay (``ablation/relay.py``) sends them to the coordinator
instead, which writes them with a :class:`FolderFiles` of its own: a worker on another machine
never writes the run folder.
"""

from __future__ import annotations

import os
import shutil
import tempfile
from abc import ABC, abstractmethod
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

from ..errors import SafeEmbodAIError
from .files import BAG_STORAGE_FILE, BAGS_DIR, RECORD_FILE, RECORDINGS_DIR, read_run_text, trial_file_name

#: The most files a trial's bag folder may hold (rosbag2: the storage file and metadata.yaml).
MAX_BAG_FILES = 16


def trajectory_file(run_dir: str | Path, trial_id: str) -> Path:
    """Where the picture of ``trial_id`` goes in a run folder."""
    return Path(run_dir) / "trajectories" / (trial_file_name(trial_id) + ".png")


def bag_file(run_dir: str | Path, trial_id: str) -> Path:
    """Where the bag of ``trial_id`` goes in a run folder that records bags."""
    return Path(run_dir) / BAGS_DIR / trial_file_name(trial_id)


def recording_file(run_dir: str | Path, trial_id: str) -> Path:
    """Where the Rerun recording of ``trial_id`` goes in a run folder (``safeembodai export RUN
    --format rrd --out RUN/recordings``), for ``view`` to link."""
    return Path(run_dir) / RECORDINGS_DIR / (trial_file_name(trial_id) + ".rrd")


class TrialFiles(ABC):
    """Receives the files of the trials a runner runs."""

    @abstractmethod
    def picture(self, trial_id: str, png: bytes) -> None:
        """Keep the trial's picture (replacing one an earlier try left); raises
        :class:`SafeEmbodAIError` naming the file when it cannot."""

    @abstractmethod
    def bag(self, trial_id: str, messages: Iterable[tuple[str, int, Any]], storage: str) -> None:
        """Keep the trial's bag, made of ``messages`` (replacing one an earlier try left)."""

    @abstractmethod
    def recording(self, trial_id: str, rrd: bytes) -> None:
        """Keep the trial's Rerun recording (replacing one an earlier try left)."""


@dataclass(frozen=True)
class ArtefactSettings:
    """Which files a run writes per trial besides its picture: a bag (``bag_storage``, ``mcap`` or
    ``sqlite3``; None for none) and a Rerun recording (``recordings``)."""

    bag_storage: str | None = None
    recordings: bool = False

    @classmethod
    def recorded(cls, run_dir: str | Path | None) -> "ArtefactSettings":
        """What the run folder's markers ask for (nothing for no folder)."""
        if run_dir is None:
            return cls()
        folder = Path(run_dir)
        return cls(bag_storage=_marker(folder, folder / BAGS_DIR / BAG_STORAGE_FILE, ("mcap", "sqlite3")),
                   recordings=_marker(folder, folder / RECORDINGS_DIR / RECORD_FILE, ("rrd",)) is not None)


def _marker(run_dir: Path, path: Path, allowed: tuple[str, ...]) -> str | None:
    try:
        text = read_run_text(path, 1024, folder=run_dir).strip()  # no symlinked bags/ or recordings/ either
    except FileNotFoundError:
        return None
    except OSError as error:
        raise SafeEmbodAIError(f"{path} is unreadable: {error}") from None
    if text not in allowed:
        raise SafeEmbodAIError(f"{path} says {text[:40]!r}: it must say {' or '.join(allowed)}")
    return text


def record_artefacts(run_dir: str | Path, *, bags: str | None = None, recordings: bool = False) -> None:
    """Write the markers that make every trial of the run folder write a bag (``bags``) and a
    recording (``recordings``) as it ends; raises :class:`SafeEmbodAIError` naming the folder."""
    for wanted, folder, name, text in ((bags, BAGS_DIR, BAG_STORAGE_FILE, bags),
                                       (recordings, RECORDINGS_DIR, RECORD_FILE, "rrd")):
        if not wanted:
            continue
        target = Path(run_dir) / folder
        try:
            target.mkdir(parents=True, exist_ok=True)
            (target / name).write_text(f"{text}\n", encoding="utf-8")
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write {target}: {error.strerror or error}") from None


@dataclass
class TrialOutputs:
    """What a runner with no run folder of its own (a Ray worker) is given instead: where files go,
    the bags and recordings the run writes, and the response cache replies are read from
    and kept in (None: none; any object with ``get(key)`` and ``put(key, reply, trial_id)``)."""

    files: TrialFiles
    settings: ArtefactSettings = ArtefactSettings()
    cache: Any = None


class FolderFiles(TrialFiles):
    """The run folder's own files."""

    def __init__(self, run_dir: str | Path) -> None:
        self.run_dir = Path(run_dir)

    def picture(self, trial_id: str, png: bytes) -> None:
        write_whole(trajectory_file(self.run_dir, trial_id), png, what="the trajectory picture")

    def bag(self, trial_id: str, messages: Iterable[tuple[str, int, Any]], storage: str) -> None:
        from ..ros.bag_export import write_bag

        write_bag(bag_file(self.run_dir, trial_id), messages, storage, replace=True)

    def recording(self, trial_id: str, rrd: bytes) -> None:
        write_whole(recording_file(self.run_dir, trial_id), rrd, what="the Rerun recording")

    def bag_folder(self, trial_id: str, files: dict[str, bytes]) -> None:
        """Put a bag made elsewhere (its files by name) in place of the trial's, whole or not at all."""
        target = bag_file(self.run_dir, trial_id)
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
            aside = Path(tempfile.mkdtemp(prefix=f".{target.name[:40]}.", suffix=".partial", dir=target.parent))
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write the bag {target}: {error.strerror or error}") from None
        try:
            partial = aside / target.name
            partial.mkdir()
            for name, data in files.items():
                (partial / name).write_bytes(data)
            if target.is_dir() and not target.is_symlink():
                shutil.rmtree(target)
            os.replace(partial, target)
        except OSError as error:
            raise SafeEmbodAIError(f"cannot write the bag {target}: {error.strerror or error} "
                                   "(the trial's result is stored; 'safeembodai export' makes its bag again)") from None
        finally:
            shutil.rmtree(aside, ignore_errors=True)


def write_whole(path: Path, data: bytes, what: str) -> None:
    """Write ``data`` to ``path`` aside, then rename it into place: the file appears whole or not at
    all. A file that cannot be written stops the run with an error naming it: the trial's result is
    already stored, and a resume draws the missing picture again."""
    partial = path.with_name(f".{path.name}.{os.getpid()}.partial")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        partial.write_bytes(data)
        os.replace(partial, path)
    except OSError as error:
        try:
            partial.unlink(missing_ok=True)
        except OSError:
            pass
        raise SafeEmbodAIError(f"cannot write {what} {path}: {error.strerror or error} "
                               f"(the trial's result is stored; resume the run once fixed)") from None


def bag_bytes(trial_id: str, messages: Iterable[tuple[str, int, Any]], storage: str) -> dict[str, bytes]:
    """The bag of ``trial_id`` as its files' bytes by name, written in a scratch folder of this machine
    under the name it has in a run folder (rosbags names its files after the bag's folder)."""
    from ..ros.bag_export import write_bag

    with tempfile.TemporaryDirectory(prefix="safeembodai-bag-") as scratch:
        folder = write_bag(Path(scratch) / trial_file_name(trial_id), messages, storage)
        return {path.name: path.read_bytes() for path in sorted(folder.iterdir()) if path.is_file()}
