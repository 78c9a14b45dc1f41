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


def test_a_remote_backend_takes_its_concurrency_by_default_and_a_memory_store_runs_one_at_a_time(
        fake_server, fake_key, tmp_path):
    fake_server.default = Reply(answer(straight(100)))
    path = _scenario(tmp_path, fake_server)
    _, done = _ablate(path, tmp_path / "runs", fake_key)
    assert "(process, 1 worker, 8 in flight per worker)" in done.stdout
    data = yaml.safe_load(path.read_text())
    data["state"] = "memory"  # cannot take worker processes: the default falls back, it does not refuse
    path.write_text(yaml.safe_dump(data))
    _, done = _ablate(path, tmp_path / "memory", fake_key)
    assert "(serial, 1 worker)" in done.stdout


def test_a_dry_run_estimates_calls_tokens_and_cost_and_sends_nothing(fake_server, fake_key, tmp_path):
    import litellm

    path = _scenario(tmp_path, fake_server)
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate", str(path), "--dry-run",
                           "--out", str(tmp_path / "runs")], capture_output=True, text=True, timeout=300,
                          env={**os.environ, "SAFEEMBODAI_TEST_KEY": fake_key, "COLUMNS": "200"})
    assert done.returncode == 0, done.stderr[-2000:]
    assert not fake_server.requests and not (tmp_path / "runs").exists()  # nothing sent, no folder
    out = done.stdout
    assert "inflight: 4 trials to run, estimated (nothing was sent)" in out
    row = next(line.split() for line in out.splitlines() if line.startswith("flatland"))
    trials, low, budget, high, prompt, answer_tokens = (int(x.replace(",", "")) for x in row[2:8])
    assert (trials, low, budget, high) == (4, 4, 8, 32)  # max_steps 2, failure_threshold 3
    assert prompt > 100 and answer_tokens > 10
    cost = sum(litellm.cost_per_token(model="gpt-4o", prompt_tokens=8 * prompt, completion_tokens=8 * answer_tokens))
    assert f"every trial uses its step budget: 8 calls, {8 * (prompt + answer_tokens):,} tokens, ${cost:,.2f}" in out


def test_a_dry_run_prices_a_known_model_without_a_key_and_says_when_a_price_is_unknown(fake_server, tmp_path):
    """Deciding before paying needs no key: the price is litellm's table's, read offline."""
    path = _scenario(tmp_path, fake_server)
    env = {k: v for k, v in os.environ.items() if k not in ("SAFEEMBODAI_TEST_KEY", "OPENAI_API_KEY")}
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate", str(path), "--dry-run"],
                          capture_output=True, text=True, timeout=300, env={**env, "COLUMNS": "200"})
    assert done.returncode == 0, done.stderr[-2000:]
    assert "every trial uses its step budget: 8 calls" in done.stdout and ", $" in done.stdout
    assert "not set" not in done.stdout and not fake_server.requests
    unknown = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate", str(path), "--dry-run", "--set",
                              "backend.options.model=openai/a-model-nobody-priced"],
                             capture_output=True, text=True, timeout=300, env={**env, "COLUMNS": "200"})
    assert unknown.returncode == 0, unknown.stderr[-2000:]
    assert "knows no price" in unknown.stdout and ", $" not in unknown.stdout
