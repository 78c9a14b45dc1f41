"""A real two-node Ray cluster, on loopback inside a network and PID namespace this test makes:
``ablate --executor ray`` gives the serial run's metrics with a relative ``--out`` and nodes started
from other folders, spreads its trials over both nodes and records each one's node, survives a node
killed mid-run with nothing lost or run twice, fails fast on a wrong address, and leaves no process.

Needs root (``unshare``) and the ray extra; CI runs as root, so it runs there. The cluster and every
command against it run in ``ray_cluster_check.py``, the namespace's first process.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path

import pytest

from processes import processes_naming

pytest.importorskip("ray", reason='the ray extra is not installed: pip install -e ".[ray]"')

pytestmark = [pytest.mark.ray, pytest.mark.slow, pytest.mark.timeout(900)]

SUPPORT = Path(__file__).resolve().parents[2] / "support"


def _namespaces_or_skip() -> None:
    if os.geteuid() != 0:
        pytest.skip("needs root to make a network namespace (unshare); CI runs as root")
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        pytest.skip("needs unshare (util-linux) and ip (iproute2)")
    probe = subprocess.run(["unshare", "--net", "--pid", "--fork", "--mount-proc", "true"], capture_output=True,
                           text=True)
    if probe.returncode != 0:
        pytest.skip(f"namespaces are unavailable here: {probe.stderr.strip()[:200]}")


@pytest.fixture(scope="module")
def cluster_report(repo):
    _namespaces_or_skip()
    work = tempfile.mkdtemp(prefix="sr-", dir="/tmp")  # short: Ray's socket paths live under it
    try:
        done = subprocess.run(["unshare", "--net", "--pid", "--fork", "--mount-proc", sys.executable,
                               str(SUPPORT / "ray_cluster_check.py"), str(repo), work],
                              capture_output=True, text=True, timeout=840)
        assert done.returncode == 0, done.stderr[-3000:]
        report = json.loads(done.stdout)
        report["left_behind"] = processes_naming(work)
        yield report
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _complete(run: dict, trials: int) -> dict:
    assert run["rc"] == 0, run["err"][-2000:] + run.get("server_logs", "")
    facts = run["facts"]
    assert len(facts["ledger"]) == len(set(facts["ledger"])) == trials  # nothing lost, nothing twice
    assert set(facts["nodes"]) == set(facts["ledger"])
    assert facts["steps"] == facts["recorded_steps"]  # every step of every trial is in the coordinator's store
    assert len(facts["pictures"]) == trials
    return facts


def test_a_relative_out_gives_a_complete_run_folder_equal_to_serial(cluster_report):
    assert cluster_report["start"]["head"] == 0 and cluster_report["start"]["node2"] == 0, cluster_report["start"]
    serial = _complete(cluster_report["serial"], 8)
    ray_run = _complete(cluster_report["ray"], 8)
    assert ray_run["metrics_csv"] == serial["metrics_csv"] and serial["metrics_csv"]
    assert ray_run["steps"] == serial["steps"] and ray_run["pictures"] == serial["pictures"]
    assert "run folder: runs/mo-" in cluster_report["ray"]["out"]  # relative, under the driver's folder only
    assert Path(ray_run["folder"]).parent.parent.name == "driver"


def test_trials_are_spread_over_both_nodes_and_each_records_its_node(cluster_report):
    nodes = Counter(_complete(cluster_report["ray"], 8)["nodes"].values())
    assert {name.split("/")[0] for name in nodes} == {"127.0.0.1", "127.0.0.2"}, nodes
    assert "at 127.0.0.1:6390" in cluster_report["ray"]["out"]  # the header names the cluster


def test_ray_client_runs_the_same_trials(cluster_report):
    client = _complete(cluster_report["client"], 4)
    assert all(node for node in client["nodes"].values())


def test_a_node_killed_mid_run_loses_and_duplicates_nothing(cluster_report):
    assert cluster_report["killed_pids"] > 0
    killed = cluster_report["killed"]
    # the lost worker was replaced; almost always a trial of it was cut off mid-way too (the node can be
    # killed in the moment between two of its trials: test_ray_recovery.py checks a cut-off trial exactly)
    assert "ray.worker_replaced" in killed["err"], killed["err"][-2000:]
    if killed["rc"] != 0:  # a clean stop is allowed: then a resume must finish it
        assert "--resume" in killed["err"]
        assert cluster_report["resumed"]["rc"] == 0, cluster_report["resumed"]["err"][-2000:]
        killed = dict(killed, rc=0)
    facts = _complete(killed, 16)
    assert facts["metrics_csv"] == _complete(cluster_report["serial4"], 16)["metrics_csv"]


def test_a_wrong_address_fails_fast_naming_it_and_makes_no_run_folder(cluster_report):
    wrong = cluster_report["wrong"]
    assert wrong["rc"] != 0 and wrong["seconds"] < 60
    assert "127.0.0.1:1" in wrong["err"] and "Traceback" not in wrong["err"]
    assert wrong["folders"] == []


def test_the_cluster_and_every_process_it_started_are_gone(cluster_report):
    assert cluster_report["left_behind"] == []
