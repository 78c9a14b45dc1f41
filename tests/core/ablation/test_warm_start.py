"""Workers forked from the warm fork server (``ablation/warm_start.py``): the warm-up imports what the
scenario's backend needs, and a forked worker still takes the coordinator's environment as it is when
the run starts, not the server's from an earlier moment."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import yaml

from fake_openai import FAKE_KEY, Reply
from safeembodai_core.ablation.warm_start import WARM_SCENARIO, can_fork_workers, start_warm_server
from safeembodai_core.testing import answer, straight

pytestmark = pytest.mark.skipif(not can_fork_workers(), reason="no fork server on this platform: workers are spawned")

#: Set only after the fork server runs: a worker sees it only if it takes the coordinator's environment.
LATE_KEY = "SAFEEMBODAI_TEST_KEY_SET_AFTER_THE_SERVER"


def _scenario(tmp_path, server) -> dict:
    return {
        "name": "warm", "trials": 2, "max_steps": 2, "seed": 3, "environments": ["flatland"],
        "backend": {"use": "gpt-4o", "options": {"api_base": server.url, "api_key_env": LATE_KEY,
                                                  "backoff_s": 0.0, "timeout_s": 10.0}},
        "arms": {"safeembodai": {"security_prefix": True, "state_management": True, "safety_validation": True}},
        "conditions": {"no_attack": {}},
    }


@pytest.mark.slow
def test_the_warm_up_imports_what_the_backend_needs(tmp_path, fake_server):
    """The module the fork server preloads builds the scenario's backend once: litellm is imported
    before any worker is forked (a worker would otherwise spend ~5 s of CPU on it)."""
    from safeembodai_core.scenario import Scenario

    scenario = Scenario.model_validate(_scenario(tmp_path, fake_server)).model_dump(mode="json")
    probe = ("import sys; import safeembodai_core.ablation.warm_start; "
             "print(int('litellm' in sys.modules), int('SAFEEMBODAI_WARM_SCENARIO' in __import__('os').environ))")
    env = {**os.environ, WARM_SCENARIO: json.dumps(scenario), LATE_KEY: FAKE_KEY}
    warmed = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, env=env)
    cold = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120,
                          env={k: v for k, v in env.items() if k != WARM_SCENARIO})
    assert warmed.stdout.split() == ["1", "0"], warmed.stderr  # imported; the scenario is not left for workers
    assert cold.stdout.split() == ["0", "0"], cold.stderr  # imported anywhere else, the module does nothing
    assert len(fake_server.requests) == 0  # warming up calls no model


@pytest.mark.slow
def test_a_forked_worker_takes_the_coordinators_environment_when_the_run_starts(tmp_path, fake_server, monkeypatch):
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    monkeypatch.delenv(LATE_KEY, raising=False)
    assert start_warm_server(None)  # running now (or already), without the key in its environment
    monkeypatch.setenv(LATE_KEY, FAKE_KEY)
    fake_server.default = Reply(answer(straight(100)))
    path = tmp_path / "warm.yaml"
    path.write_text(yaml.safe_dump(_scenario(tmp_path, fake_server)))
    plugins = load_plugins()
    scenario = load_scenario(path, [], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder.create(tmp_path / "runs", scenario), workers=1, concurrency=2)
    try:
        results = ablation.run()
    finally:
        ablation.close()
    assert all(r.outcome.value != "error" for r in results), [r.detail for r in results]
    assert fake_server.requests and all(r.headers.get("authorization") == f"Bearer {FAKE_KEY}"
                                        for r in fake_server.requests)
