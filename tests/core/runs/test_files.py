"""A file of a folder from elsewhere is read only when it is a regular file reached from the folder with no
symlink anywhere below it (``run_files.open_inside``): a symlinked ``figures/``, ``bags/`` or a response
cache's subfolder leads nowhere, as a symlinked file does; every reader of a run folder goes through it."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.runs.files import UnreadableFile, folder_names, open_inside, read_regular_file, read_run_text

SECRET = b"\x89PNG\r\n\x1a\nTOP-SECRET"


@pytest.fixture
def run(tmp_path) -> Path:
    """A run folder whose ``figures/`` is a symlink to a folder outside it, beside a real ``report/``."""
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "a.png").write_bytes(SECRET)
    folder = tmp_path / "run"
    (folder / "report").mkdir(parents=True)
    (folder / "report" / "b.png").write_bytes(b"\x89PNG\r\n\x1a\nmine")
    (folder / "figures").symlink_to(outside)
    return folder


def test_a_file_through_a_symlinked_folder_is_refused_naming_it(run):
    with pytest.raises(UnreadableFile, match="figures is a symlink") as refused:
        open_inside(run, run / "figures" / "a.png")
    assert refused.value.reason == "figures is a symlink (not followed)"
    assert read_regular_file(run / "figures" / "a.png", 1000, folder=run) is None
    with pytest.raises(SafeEmbodAIError, match="figures is a symlink"):
        read_run_text(run / "figures" / "a.png", 1000, folder=run)
    with pytest.raises(UnreadableFile, match="figures is a symlink"):
        folder_names(run, run / "figures")
    assert read_regular_file(run / "report" / "b.png", 1000, folder=run) == b"\x89PNG\r\n\x1a\nmine"
    assert folder_names(run, run / "report") == ["b.png"]


def test_a_symlinked_folder_deeper_down_is_refused_too(run, tmp_path):
    (run / "report" / "deeper").symlink_to(tmp_path / "outside")
    with pytest.raises(UnreadableFile, match="report/deeper is a symlink"):
        open_inside(run, run / "report" / "deeper" / "a.png")


def test_dot_dot_a_path_outside_and_a_file_as_a_folder_are_refused(run, tmp_path):
    for path, why in ((run / "report" / ".." / "report" / "b.png", "not a file inside"),
                      (tmp_path / "outside" / "a.png", "not inside"),
                      (run / "report" / "b.png" / "c", "report/b.png is not a folder"),
                      (run / "report", "a folder")):
        with pytest.raises(UnreadableFile, match=why):
            open_inside(run, path)
    with pytest.raises(FileNotFoundError, match="none.png"):
        open_inside(run, run / "report" / "none.png")
    with pytest.raises(FileNotFoundError):
        open_inside(run, run / "none" / "none.png")


@pytest.mark.skipif(not hasattr(os, "mkfifo") or not Path("/dev/zero").exists(), reason="no FIFOs or devices here")
def test_a_fifo_or_a_device_below_the_folder_is_refused_at_once(run):
    os.mkfifo(run / "report" / "pipe.png")
    with pytest.raises(UnreadableFile, match="not a regular file"):
        open_inside(run, run / "report" / "pipe.png")
    with pytest.raises(UnreadableFile, match="report/pipe.png is not a folder"):  # a FIFO on the way
        open_inside(run, run / "report" / "pipe.png" / "a.png")
    with pytest.raises(UnreadableFile, match="not a regular file"):
        open_inside(Path("/dev"), Path("/dev/zero"))


def test_a_run_folders_markers_are_not_read_through_a_symlinked_folder(tmp_path):
    from safeembodai_core.runs.trial_files import ArtefactSettings

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    (elsewhere / "storage").write_text("mcap\n")
    (elsewhere / "record").write_text("rrd\n")
    run = tmp_path / "run"
    run.mkdir()
    (run / "bags").symlink_to(elsewhere)
    with pytest.raises(SafeEmbodAIError, match="bags is a symlink"):
        ArtefactSettings.recorded(run)
    (run / "bags").unlink()
    (run / "recordings").symlink_to(elsewhere)
    with pytest.raises(SafeEmbodAIError, match="recordings is a symlink"):
        ArtefactSettings.recorded(run)


def test_a_response_caches_symlinked_subfolder_is_a_miss(tmp_path):
    from safeembodai_core.loop.response_cache import ResponseCache
    from safeembodai_core.models.reply import BackendReply

    cache = ResponseCache(tmp_path / "responses")
    key = "ab" + "0" * 62 + ":1"
    cache.put(key, BackendReply(text='{"x": 1}'))
    assert cache.get(key) is not None
    elsewhere = tmp_path / "elsewhere"
    (cache.folder / "ab").rename(elsewhere)
    (cache.folder / "ab").symlink_to(elsewhere)  # the same reply, reached through a symlinked folder
    assert cache.get(key) is None


def test_without_openat_each_folder_on_the_way_is_checked(run, monkeypatch):
    """Where ``open`` takes no ``dir_fd`` (not POSIX), each folder on the way is checked before the open."""
    from safeembodai_core.runs import files as run_files

    monkeypatch.setattr(run_files, "_IN_FOLDER", False)
    with pytest.raises(UnreadableFile, match="figures is a symlink"):
        open_inside(run, run / "figures" / "a.png")
    with pytest.raises(UnreadableFile, match="figures is a symlink"):
        folder_names(run, run / "figures")
    assert read_regular_file(run / "report" / "b.png", 1000, folder=run) == b"\x89PNG\r\n\x1a\nmine"
    assert folder_names(run, run / "report") == ["b.png"]
