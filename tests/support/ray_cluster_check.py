"""Runs inside a private network and PID namespace (``test_ray_cluster.py`` starts it with ``unshare``):
a real two-node Ray cluster on loopback, ablations against it, and what they left, as JSON on stdout.

Node 1 (the head) listens on 127.0.0.1, node 2 on 127.0.0.2; each is started from its own working
directory, and the ablations from a third, with a relative ``--out``. Nothing binds or sends outside
this namespace's loopback. When this script (the namespace's first process) ends, the kernel ends
every process of the namespace: the cluster cannot outlive the test.
"""

from __future__ import annotations

import json
import os
import secrets
import signal
import subprocess
import sys
import time
from pathlib import Path

PORT = 6390
CLIENT_PORT = 10001


def sh(*args: str, cwd: Path, env: dict[str, str], timeout: float = 120) -> subprocess.CompletedProcess:
    return subprocess.run(list(args), cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def ablate(args: list[str], cwd: Path, env: dict[str, str], timeout: float = 420) -> dict:
    start = time.monotonic()
    done = sh(sys.executable, "-m", "safeembodai_core", "ablate", *args, cwd=cwd, env=env, timeout=timeout)
    return {"rc": done.returncode, "seconds": time.monotonic() - start, "out": done.stdout[-4000:],
            "err": done.stderr[-4000:]}


def run_folder(output: str, cwd: Path) -> Path | None:
    for line in output.splitlines():
        if line.startswith("run folder: "):
            return cwd / line.removeprefix("run folder: ").strip()
    return None


def facts(folder: Path | None) -> dict:
    """What a run folder holds: its ledger, each trial's node and step count, pictures, metrics.csv."""
    if folder is None or not folder.is_dir():
        return {"folder": None}
    from safeembodai_core.ablation import RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.runs.runner import ScenarioRunner

    run = RunFolder(folder)
    runner = ScenarioRunner(run.scenario(), load_plugins(), run_dir=folder)
    try:
        results = runner.state.results()
        steps = {r.spec.trial_id: len(runner.state.steps(r.spec.trial_id)) for r in results}
    finally:
        runner.close()
    metrics = folder / "metrics.csv"
    return {"folder": str(folder), "ledger": run.finished() or [],
            "nodes": {r.spec.trial_id: r.node for r in results}, "steps": steps,
            "recorded_steps": {r.spec.trial_id: r.steps for r in results},
            "pictures": sorted(p.name for p in (folder / "trajectories").glob("*.png")),
            "metrics_csv": metrics.read_text() if metrics.exists() else None}


def node_processes(address: str) -> list[int]:
    """Pids of this namespace's processes of the node at ``address``: its raylet and daemons, and every
    process they started (the node's workers: a node that is lost takes them with it)."""
    commands, parents = {}, {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                command = (entry / "cmdline").read_bytes().replace(b"\0", b" ")
                commands[int(entry.name)] = command.decode(errors="replace")
                parents[int(entry.name)] = int((entry / "stat").read_text().rpartition(")")[2].split()[1])
            except (OSError, ValueError, IndexError):
                continue
    chosen = {pid for pid, command in commands.items()
              if f"node_ip_address={address}" in command or f"node-ip-address={address}" in command}
    grown = True
    while grown:
        more = {pid for pid, parent in parents.items() if parent in chosen} - chosen
        chosen |= more
        grown = bool(more)
    return sorted(chosen)


def main() -> None:
    repo, work = Path(sys.argv[1]), Path(sys.argv[2])
    subprocess.run(["ip", "link", "set", "lo", "up"], check=True)
    env = dict(os.environ, RAY_USAGE_STATS_ENABLED="0", RAY_AUTH_MODE="token", RAY_AUTH_TOKEN=secrets.token_hex(32),
               HOME=str(work / "home"), RAY_TMPDIR=str(work / "t"), PYTHONUNBUFFERED="1",
               RAY_health_check_period_ms="1000", RAY_health_check_failure_threshold="3",
               # Ray Client's server on the head starts a server per client: on a loaded 2-core machine that
               # took more than its 30 s once (the client then fails); the run's own --connect-timeout follows
               RAY_CLIENT_SERVER_CHECK_CHANNEL_TIMEOUT_S="150")
    env.pop("RAY_ADDRESS", None)
    dirs = {name: work / name for name in ("home", "t", "head", "node2", "driver")}
    for folder in dirs.values():
        folder.mkdir(parents=True, exist_ok=True)
    ray = str(Path(sys.executable).with_name("ray"))
    report: dict = {}
    head = sh(ray, "start", "--head", "--node-ip-address", "127.0.0.1", "--port", str(PORT), "--num-cpus", "1",
              "--include-dashboard", "false", "--disable-usage-stats", "--ray-client-server-port", str(CLIENT_PORT),
              cwd=dirs["head"], env=env)
    node2 = sh(ray, "start", "--address", f"127.0.0.1:{PORT}", "--node-ip-address", "127.0.0.2", "--num-cpus", "1",
               "--disable-usage-stats", cwd=dirs["node2"], env=env)
    report["start"] = {"head": head.returncode, "node2": node2.returncode, "err": (head.stderr + node2.stderr)[-2000:]}
    address = f"127.0.0.1:{PORT}"
    scenario = str(repo / "scenarios" / "mo.yaml")
    driver = dirs["driver"]

    # a complete run folder with a relative --out, the nodes started from other folders
    report["serial"] = ablate([scenario, "--set", "trials=2", "--out", "serial"], driver, env)
    report["serial"]["facts"] = facts(run_folder(report["serial"]["out"], driver))
    report["ray"] = ablate([scenario, "--set", "trials=2", "--executor", "ray", "--workers", "2", "--address", address,
                            "--out", "runs"], driver, env)
    report["ray"]["facts"] = facts(run_folder(report["ray"]["out"], driver))

    # Ray Client
    # Ray's client server on the head dies now and then as it forks a server for a new client (a gRPC race,
    # ray-project/ray#63202, open): the connection then fails, and a new invocation is the documented remedy
    for attempt in range(1, 4):
        report["client"] = ablate([scenario, "--set", "trials=1", "--executor", "ray", "--workers", "2", "--address",
                                   f"ray://127.0.0.1:{CLIENT_PORT}", "--connect-timeout", "60", "--out",
                                   f"client{attempt}", "--no-report"], driver, env)
        report["client"]["attempts"] = attempt
        if "cannot connect to the Ray cluster" not in report["client"]["err"]:
            break
    report["client"]["facts"] = facts(run_folder(report["client"]["out"], driver))
    if report["client"]["rc"] != 0:  # what the head's Ray Client server said, for the test's message
        logs = sorted((work / "t").glob("ray/session_*/logs/ray_client_server*.err"))
        report["client"]["server_logs"] = "".join(f"== {p.name}\n{p.read_text(errors='replace')[-1500:]}"
                                                  for p in logs)

    # a node lost mid-run
    report["serial4"] = ablate([scenario, "--set", "trials=4", "--out", "serial4"], driver, env)
    report["serial4"]["facts"] = facts(run_folder(report["serial4"]["out"], driver))
    start = time.monotonic()
    process = subprocess.Popen([sys.executable, "-m", "safeembodai_core", "ablate", scenario, "--set", "trials=4",
                                "--executor", "ray", "--workers", "2", "--address", address, "--out", "killed"],
                               cwd=driver, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    killed: list[int] = []
    while process.poll() is None and time.monotonic() - start < 300:
        ledgers = list((driver / "killed").glob("*/finished.jsonl"))
        if ledgers and len(ledgers[0].read_text().splitlines()) >= 3:
            killed = node_processes("127.0.0.2")
            for pid in killed:
                try:
                    os.kill(pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
            break
        time.sleep(0.2)
    report["killed_at_s"] = time.monotonic() - start
    report["killed_pids"] = len(killed)
    out, err = process.communicate(timeout=420)
    report["killed"] = {"rc": process.returncode, "seconds": time.monotonic() - start, "out": out[-4000:],
                        "err": err[-4000:]}
    folder = run_folder(out, driver) or next(iter((driver / "killed").glob("*")), None)
    if process.returncode != 0 and folder is not None:  # a clean stop: resume it on what is left
        report["resumed"] = ablate(["--resume", str(folder)] + ["--executor", "ray", "--workers", "2", "--address",
                                                                address], driver, env)
    report["killed"]["facts"] = facts(folder)

    # a wrong address
    report["wrong"] = ablate([scenario, "--set", "trials=1", "--executor", "ray", "--address", "127.0.0.1:1",
                              "--out", "wrong"], driver, env, timeout=120)
    report["wrong"]["folders"] = sorted(p.name for p in (driver / "wrong").glob("*")) if (driver / "wrong").exists() \
        else []
    json.dump(report, sys.stdout)


if __name__ == "__main__":
    main()
