"""Under Ray, SIGTERM stops a run exactly as without it (exit 143, the interrupted line with the resume
command, no traceback), the Ray it started is gone, and a resume on Ray finishes the run."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from processes import processes_naming

pytest.importorskip("ray", reason='the ray extra is not installed: pip install -e ".[ray]"')

pytestmark = [pytest.mark.ray, pytest.mark.slow]


def _ledger(out: Path) -> list[str]:
    ledgers = list(out.glob("*/finished.jsonl"))
    return ledgers[0].read_text().splitlines() if ledgers else []


def test_sigterm_under_ray_is_the_documented_stop_and_resume_finishes(repo, tmp_path):
    scratch = tempfile.mkdtemp(prefix="sr-", dir="/tmp")  # Ray's sockets live under RAY_TMPDIR: a short path
    env = dict(os.environ, RAY_TMPDIR=scratch, HOME=scratch, RAY_USAGE_STATS_ENABLED="0")
    env.pop("RAY_ADDRESS", None)
    out = tmp_path / "runs"
    command = [sys.executable, "-m", "safeembodai_core", "ablate", str(repo / "scenarios" / "quickstart.yaml"),
               "--set", "trials=8", "--set", "max_steps=6", "--executor", "ray", "--workers", "2", "--out",
               str(out), "--no-report"]
    try:
        process = subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                   start_new_session=True)
        deadline = time.monotonic() + 120
        while len(_ledger(out)) < 2 and time.monotonic() < deadline and process.poll() is None:
            time.sleep(0.1)
        assert process.poll() is None, process.communicate()
        process.send_signal(signal.SIGTERM)
        stdout, stderr = process.communicate(timeout=60)
        [folder] = list(out.glob("quickstart-*"))
        assert process.returncode == 143, stderr[-2000:]
        assert "interrupted (SIGTERM)" in stdout and f"resume with --resume {folder}" in stdout.replace("\n", "")
        assert "Traceback" not in stderr
        time.sleep(1)
        assert processes_naming(scratch) == []  # the Ray this run started ended with it

        done = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate", "--resume", str(folder),
                               "--executor", "ray", "--workers", "2", "--no-report"], env=env, capture_output=True,
                              text=True, timeout=300)
        assert done.returncode == 0, done.stderr[-2000:]
        ledger = _ledger(out)
        assert len(ledger) == len(set(ledger)) == 32  # 4 cells x 8 trials: none lost, none twice
    finally:
        subprocess.run(["pkill", "-9", "-f", scratch], check=False)  # whatever a failed check left running
        shutil.rmtree(scratch, ignore_errors=True)
