"""No process of a run outlives its coordinator; SIGTERM stops a run like Ctrl-C; resume then finishes it
with no trial lost, repeated or changed."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.runs.folder import RunLock
from safeembodai_core.scenario import load_scenario

DEADLINE_S = 10.0
OVERRIDES = ["--set", "trials=25", "--set", "max_steps=8"]


def alive_in_group(pgid: int) -> set[int]:
    """Pids of live (not zombie) processes in process group ``pgid``, from /proc."""
    pids = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        state, _ppid, group = stat.rsplit(")", 1)[1].split()[:3]
        if int(group) == pgid and state != "Z":
            pids.add(int(entry.name))
    return pids


def wait_until(condition, deadline_s: float = DEADLINE_S, every_s: float = 0.05) -> bool:
    deadline = time.monotonic() + deadline_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(every_s)
    return condition()


def stored(folder: Path):
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    if not (folder / "results.sqlite").exists():
        return []
    store = SqliteStateStore(folder / "results.sqlite")
    try:
        return store.results()
    finally:
        store.close()


def comparable(results):
    return {r.spec.trial_id: r.model_dump(exclude={"wall_time_s"}) for r in results}


class Coordinator:
    """``safeembodai ablate`` in its own session (its pgid is its pid); every process left is killed at the end."""

    def __init__(self, repo: Path, out: Path, *args: str) -> None:
        self.out = out
        command = [sys.executable, "-m", "safeembodai_core", "ablate", str(repo / "scenarios" / "quickstart.yaml"),
                   *OVERRIDES, "--out", str(out), "--no-report", *args]
        self.process = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                        start_new_session=True)

    def folder(self) -> Path | None:
        runs = list(self.out.glob("quickstart-*"))
        return runs[0] if runs else None

    def wait_for_results(self, count: int) -> Path:
        assert wait_until(lambda: self.folder() is not None and len(stored(self.folder())) >= count, 120), \
            "the ablation did not record trials in time"
        return self.folder()

    def cleanup(self) -> None:
        for pid in alive_in_group(self.process.pid):
            try:
                os.kill(pid, signal.SIGKILL)
            except ProcessLookupError:
                pass
        if self.process.poll() is None:
            self.process.kill()
        self.process.communicate()


@pytest.mark.slow
def test_sigterm_stops_a_serial_run_cleanly(repo, tmp_path):
    coordinator = Coordinator(repo, tmp_path)
    try:
        folder = coordinator.wait_for_results(2)
        coordinator.process.send_signal(signal.SIGTERM)
        stdout, stderr = coordinator.process.communicate(timeout=60)
    finally:
        coordinator.cleanup()
    assert coordinator.process.returncode == 143, stderr
    assert "interrupted (SIGTERM)" in stdout and f"resume with --resume {folder}" in stdout.replace("\n", "")
    assert "Traceback" not in stderr


@pytest.mark.slow
@pytest.mark.parametrize(("stop", "parallel"), [
    (signal.SIGKILL, ("--workers", "2")), (signal.SIGTERM, ("--workers", "2")),
    (signal.SIGKILL, ("--workers", "2", "--concurrency", "3")),  # three trials in flight in each worker's threads
], ids=["SIGKILL", "SIGTERM", "SIGKILL-concurrency"])
@pytest.mark.slow
def test_killed_coordinator_leaves_no_process_and_resume_completes_the_run(repo, plugins, tmp_path, stop, parallel):
    coordinator = Coordinator(repo, tmp_path / "runs", *parallel)
    try:
        folder = coordinator.wait_for_results(3)
        children = alive_in_group(coordinator.process.pid) - {coordinator.process.pid}
        assert len(children) >= 2  # the two workers (and multiprocessing's resource tracker)
        os.kill(coordinator.process.pid, stop)  # the coordinator only: its workers must end by themselves
        coordinator.process.wait(timeout=60)
        assert wait_until(lambda: not alive_in_group(coordinator.process.pid)), \
            f"still alive {DEADLINE_S:g} s after the coordinator: {alive_in_group(coordinator.process.pid)}"
    finally:
        coordinator.cleanup()
    if stop == signal.SIGTERM:
        assert coordinator.process.returncode == 143
    before = {r.spec.trial_id: r for r in stored(folder)}
    assert 3 <= len(before) < 100, len(before)

    resumed = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate",
                              str(repo / "scenarios" / "quickstart.yaml"),
                              *OVERRIDES, *parallel, "--no-report", "--resume", str(folder)],
                             capture_output=True, text=True, timeout=300)
    assert resumed.returncode == 0, resumed.stderr
    after = stored(folder)
    assert len(after) == len({r.spec.trial_id for r in after}) == 100
    by_id = {r.spec.trial_id: r for r in after}
    assert all(by_id[trial_id].wall_time_s == r.wall_time_s for trial_id, r in before.items())  # not run again
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=25", "max_steps=8"], plugins.registry)
    reference = Ablation(scenario, plugins, RunFolder(tmp_path / "uninterrupted"))
    try:
        assert comparable(after) == comparable(reference.run())
    finally:
        reference.close()


WORKER = textwrap.dedent("""
    import os, sys, threading
    from safeembodai_core.ablation import lifeline
    from safeembodai_core.runs.folder import hold_worker_lock
    if sys.argv[2] == "watchdog-only":
        lifeline._die_with_parent = lambda: None
    lifeline.bind_to_coordinator(os.getppid())
    hold_worker_lock(sys.argv[1])
    print(os.getpid(), flush=True)
    threading.Event().wait()  # blocked for good, like a worker waiting on the call queue
""")

COORDINATOR = textwrap.dedent("""
    import subprocess, sys, time
    worker = subprocess.Popen([sys.executable, "-c", sys.argv[1], sys.argv[2], sys.argv[3]], \
stdout=subprocess.PIPE, text=True)
    print(worker.stdout.readline().strip(), flush=True)
    time.sleep(600)
""")


@pytest.mark.parametrize("how", ["pdeathsig", "watchdog-only"])
@pytest.mark.slow
def test_a_blocked_worker_exits_when_its_coordinator_is_killed(tmp_path, how):
    coordinator = subprocess.Popen([sys.executable, "-c", COORDINATOR, WORKER, str(tmp_path), how],
                                   stdout=subprocess.PIPE, text=True, start_new_session=True)
    try:
        worker = int(coordinator.stdout.readline())
        assert worker in alive_in_group(coordinator.pid)
        coordinator.kill()
        coordinator.wait()
        assert wait_until(lambda: worker not in alive_in_group(coordinator.pid)), (
            f"worker {worker} outlived its coordinator")
    finally:
        for pid in alive_in_group(coordinator.pid):
            os.kill(pid, signal.SIGKILL)
        coordinator.stdout.close()
    # A killed process whose other threads are still exiting already reads "Z" in /proc but keeps
    # its files (and lock) until its last thread is gone: give it the deadline, as a resume does.
    lock = RunLock(tmp_path, wait_s=DEADLINE_S)
    lock.acquire()  # nothing holds the workers lock any more
    lock.release()


FORKING_WORKER = textwrap.dedent("""
    import os, sys, time
    from safeembodai_core.runs.folder import hold_worker_lock
    hold_worker_lock(sys.argv[1])
    child = os.fork()
    if child == 0:  # the child says so itself: its at-fork handlers have run by then
        print(os.getpid(), flush=True)
        time.sleep(600)
        os._exit(0)
    time.sleep(600)
""")


def test_only_the_worker_itself_holds_the_workers_lock_not_what_it_forks(tmp_path):
    holder = subprocess.Popen([sys.executable, "-c", FORKING_WORKER, str(tmp_path)], stdout=subprocess.PIPE, text=True,
                              start_new_session=True)
    try:
        child = int(holder.stdout.readline())
        holder.kill()
        holder.wait()
        assert child in alive_in_group(holder.pid)  # the forked child lives on ...
        lock = RunLock(tmp_path, wait_s=0.0)
        lock.acquire()  # ... without the worker's lock
        lock.release()
    finally:
        for pid in alive_in_group(holder.pid):
            os.kill(pid, signal.SIGKILL)
        holder.stdout.close()
