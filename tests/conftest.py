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
    from safeembodai_core.plugin.manager import load_plugins

    return load_plugins(environ={})


@pytest.fixture(scope="session")
def built_plugins():
    """One plugin set for the whole session, for tests that only build components from it."""
    from safeembodai_core.plugin.manager import load_plugins

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
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.runs.runner import ScenarioRunner, trial_spec

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
    from safeembodai_core.runs.runner import ScenarioRunner

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

    from safeembodai_core.scenario.reading import checked_scenario
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


# A small MO run recorded with bags, shared by the bag tests (tests/core/ros, tests/core/guard): one ablation
# per session.
@pytest.fixture(scope="session")
def bag_run(tmp_path_factory):
    """``scenarios/mo.yaml``, one trial per cell, a careless mock pilot (so the guard refuses plans),
    run with ``ablate --bags mcap``: (scenario, run folder, results, store steps by trial id)."""
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins(environ={})
    scenario = load_scenario(REPO / "scenarios" / "mo.yaml", [
        "trials=1", "seed=5", "max_steps=8",
        "backend={use: mock, options: {ignore_clearance_p: 0.9, malformed_p: 0.2}}"],
        plugins.registry)
    path = tmp_path_factory.mktemp("bag-run") / "run"
    ablation = Ablation(scenario, plugins, RunFolder(path), bags="mcap")
    try:
        results = ablation.run()
        steps = {r.spec.trial_id: ablation.store.steps(r.spec.trial_id) for r in results}
    finally:
        ablation.close()
    return scenario, path, results, steps


@pytest.fixture(scope="session")
def moving_bag_run(tmp_path_factory):
    """``scenarios/dynamic.yaml``'s ``told`` arm, named ``moving`` here (the moving-obstacle rule, which
    reads the earlier scans) in DO, three trials, run with ``ablate --bags mcap``: as :func:`bag_run`.
    Not the shipped ``moving`` arm: its ``fresh_scan`` judges a reading the bag does not hold (the bag's
    scans are the steps'), so ``guard-bag`` cannot judge its plans as the trial did."""
    import yaml

    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    data = yaml.safe_load((REPO / "scenarios" / "dynamic.yaml").read_text(encoding="utf-8"))
    data.update(arms={"moving": data["arms"]["told"]}, environments=data["environments"][:1], trials=3,
                max_steps=12, conditions={"no_attack": {}})
    folder = tmp_path_factory.mktemp("moving-bag-run")
    (folder / "moving.yaml").write_text(yaml.safe_dump(data), encoding="utf-8")
    plugins = load_plugins(environ={})
    scenario = load_scenario(folder / "moving.yaml", [], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(folder / "run"), bags="mcap")
    try:
        results = ablation.run()
        steps = {r.spec.trial_id: ablation.store.steps(r.spec.trial_id) for r in results}
    finally:
        ablation.close()
    return scenario, folder / "run", results, steps


#: ros-mcp (PyPI, unchanged) from a virtual environment of its own: its opencv-python would overwrite our
#: opencv-python-headless (both are cv2); .ci/run builds it and names its script in SAFEEMBODAI_ROS_MCP
ROS_MCP_INSTALL = ("ros-mcp runs from a virtual environment of its own: python -m venv ros-mcp-venv && "
                   "ros-mcp-venv/bin/pip install ros-mcp==3.1.2, then SAFEEMBODAI_ROS_MCP=ros-mcp-venv/bin/ros-mcp")


@pytest.fixture(scope="session")
def ros_mcp_script():
    """The ros-mcp console script (``SAFEEMBODAI_ROS_MCP``, else ``ros-mcp`` on the PATH); the test skips, saying
    how to install it, without one."""
    import shutil

    script = os.environ.get("SAFEEMBODAI_ROS_MCP") or shutil.which("ros-mcp")
    if script is None:
        pytest.skip(f"ros-mcp is not installed: {ROS_MCP_INSTALL}")
    assert Path(script).is_file(), f"SAFEEMBODAI_ROS_MCP={script} is no file: {ROS_MCP_INSTALL}"
    return script
