"""Shared fixtures. Tests never need network access, an API key or a display.

Helper modules (the fake OpenAI-compatible server, reply strategies, backend helpers) live in
tests/support/, which pyproject's ``pythonpath`` puts on ``sys.path``: ``from fake_openai import Reply``."""

from __future__ import annotations

import contextlib
import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("LITELLM_LOCAL_MODEL_COST_MAP", "True")


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture
def plugins():
    """A fresh plugin set (built-ins and installed entry points), isolated per test."""
    from safeembodai_core.plugins import load_plugins

    return load_plugins(environ={})


@pytest.fixture(scope="session")
def built_plugins():
    """One plugin set for the whole session, for tests that only build components from it."""
    from safeembodai_core.plugins import load_plugins

    return load_plugins(environ={})


@pytest.fixture
def fake_server():
    """The fake OpenAI-compatible server (tests/support/fake_openai.py), closed after the test."""
    from fake_openai import FakeOpenAI

    with FakeOpenAI() as server:
        yield server


@pytest.fixture
def fake_key(monkeypatch) -> str:
    """A fake API key in ``SAFEEMBODAI_TEST_KEY`` (the backends' ``api_key_env`` in the tests)."""
    from fake_openai import FAKE_KEY

    monkeypatch.setenv("SAFEEMBODAI_TEST_KEY", FAKE_KEY)
    return FAKE_KEY


@pytest.fixture
def cli_runner():
    from click.testing import CliRunner

    return CliRunner()


@pytest.fixture
def python() -> str:
    return sys.executable


def run_cell(scenario, arm: str, condition: str, index: int = 0, plugins=None):
    """Run trial ``index`` of one cell; return (result, steps, prompts sent to the scripted backend, if it is one)."""
    from safeembodai_core.loop import run_trial
    from safeembodai_core.plugins import load_plugins
    from safeembodai_core.runner import ScenarioRunner, trial_spec

    plugins = plugins or load_plugins(environ={})
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, scenario.environments[0].key, arm, condition, index)
        parts = runner.parts(spec)
        result = run_trial(spec, parts, runner.settings(arm), plugins)
        return result, runner.state.steps(spec.trial_id), list(getattr(parts.backend, "prompts", ()))
    finally:
        runner.close()


def ablate_into(scenario, plugins, path):
    """Run every trial of ``scenario`` into the run folder ``path``: (scenario, plugins, path, results)."""
    from safeembodai_core.ablation import Ablation, RunFolder

    ablation = Ablation(scenario, plugins, RunFolder(path))
    try:
        results = ablation.run()
    finally:
        ablation.close()
    return scenario, plugins, path, results


@pytest.fixture(scope="session")
def ablated():
    """:func:`ablate_into`, for module-scoped fixtures that run a whole ablation once."""
    return ablate_into


@contextlib.contextmanager
def open_run_store(scenario, plugins, path):
    """The state store of the run folder ``path``, open as ``safeembodai report`` opens it."""
    from safeembodai_core.runner import ScenarioRunner

    runner = ScenarioRunner(scenario, plugins, run_dir=path)
    try:
        yield runner.state
    finally:
        runner.close()


@pytest.fixture(scope="session")
def run_store():
    """:func:`open_run_store`: ``with run_store(scenario, plugins, path) as store: ...``."""
    return open_run_store


@pytest.fixture
def cell():
    """Run one trial of a scenario cell and keep the prompts the scripted backend received."""
    return run_cell


@pytest.fixture
def serve_robot(repo, tmp_path):
    """A room of a scenario served on a free port, in a thread, for clients no one here wrote (roslibpy,
    ros-mcp). ``serve_robot("scenarios/of.yaml", speed=2.0)``: a started session (its ``port``); stopped
    after the test."""
    running = []

    import threading

    from safeembodai_core.ablation.plan import checked_scenario
    from safeembodai_core.serve_robot.session import prepare_session

    def start(scenario: str = "scenarios/mo.yaml", **options):
        loaded, plugins = checked_scenario(repo / scenario)
        session = prepare_session(loaded, plugins, out=tmp_path / "runs", port=0, **options)
        ready = threading.Event()
        thread = threading.Thread(target=session.serve, kwargs={"on_ready": lambda _: ready.set()}, daemon=True)
        thread.start()
        assert ready.wait(20), "serve-robot did not start"
        running.append((session, thread))
        return session

    yield start
    for session, thread in running:
        session.stop("test over")
        thread.join(20)
