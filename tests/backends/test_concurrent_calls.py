"""Trials that wait on a remote model, in flight together (``ablate --concurrency``), against the fake
OpenAI-compatible server: the calls overlap, and a burst of 429s slows the run down instead of
ending its trials as ``error``."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import yaml

from fake_openai import Hang, Reply, Status
from safeembodai_core.testing import answer, straight

pytestmark = pytest.mark.slow


def _scenario(tmp_path, server, **backend):
    data = {
        "name": "inflight", "trials": 4, "max_steps": 2, "seed": 5, "environments": ["flatland"],
        "backend": {"use": "gpt-4o", "options": {"api_base": server.url, "api_key_env": "SAFEEMBODAI_TEST_KEY",
                                                  "backoff_s": 0.0, "timeout_s": 10.0, **backend}},
        "arms": {"safeembodai": {"security_prefix": True, "state_management": True, "safety_validation": True}},
        "conditions": {"no_attack": {}},
    }
    path = tmp_path / "inflight.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


def _ablate(path, out, key, *args):
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "--log-level", "info", "ablate", str(path),
                           "--out", str(out), "--no-report", *args], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "SAFEEMBODAI_TEST_KEY": key})
    assert done.returncode == 0, done.stderr[-3000:]
    [run] = out.iterdir()
    return run, done


def _outcomes(run):
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    store = SqliteStateStore(run / "results.sqlite")
    try:
        return sorted(r.outcome.value for r in store.results())
    finally:
        store.close()


def test_concurrency_keeps_that_many_calls_in_flight(fake_server, fake_key, tmp_path):
    fake_server.default = Hang(1.5, then=Reply(answer(straight(100))))
    _ablate(_scenario(tmp_path, fake_server), tmp_path / "runs", fake_key, "--concurrency", "4")
    assert fake_server.peak_in_flight == 4  # all four trials were waiting on their model at once
    assert len(fake_server.requests) >= 4


def test_a_429_burst_slows_the_run_and_every_trial_is_scored(fake_server, fake_key, tmp_path):
    """Twenty 429s (Retry-After 0.5 s) before any answer, four trials in flight, one retry each: the
    run waits the burst out (a hold-off shared by the trials) and no trial ends in ``error``."""
    fake_server.push(*[Status(429, retry_after=0.5)] * 20)
    fake_server.default = Reply(answer(straight(100)))
    run, done = _ablate(_scenario(tmp_path, fake_server, max_retries=1, backoff_max_s=5.0), tmp_path / "runs",
                        fake_key, "--concurrency", "4")
    assert "error" not in _outcomes(run) and len(_outcomes(run)) == 4
    finished = [json.loads(line) for line in (run / "finished.jsonl").read_text().splitlines() if line.strip()]
    assert len(finished) == 4
    assert sum(r.body.get("model") is not None for r in fake_server.requests) >= 24
