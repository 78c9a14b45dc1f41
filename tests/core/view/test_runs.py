"""What the site reads of a run folder (``view/runs.py``) never blocks on it: its lock is probed
without waiting, and a FIFO or a symlink in its place is no lock."""

from __future__ import annotations

import os
import threading

import pytest

from safeembodai_core.runs.folder import COORDINATOR_LOCK
from safeembodai_core.view.runs import running


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_as_the_lock_is_no_lock_and_never_blocks(tmp_path):
    os.mkfifo(tmp_path / COORDINATOR_LOCK)
    seen: list[bool] = []
    probe = threading.Thread(target=lambda: seen.append(running(tmp_path)), daemon=True)
    probe.start()
    probe.join(5)
    assert seen == [False], "running() blocked on a FIFO"


def test_a_symlink_as_the_lock_is_no_lock_and_a_held_lock_is_seen(tmp_path):
    fcntl = pytest.importorskip("fcntl")
    run = tmp_path / "run"
    run.mkdir()
    elsewhere = tmp_path / "elsewhere.lock"
    elsewhere.write_text("")
    (run / COORDINATOR_LOCK).symlink_to(elsewhere)
    with open(elsewhere) as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        assert running(run) is False  # a lock held elsewhere, reached through a symlink: not this run's
        (run / COORDINATOR_LOCK).unlink()
        os.link(elsewhere, run / COORDINATOR_LOCK)  # the same locked file, now the run's own
        assert running(run) is True
