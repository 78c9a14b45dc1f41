"""Fixtures for the defence tests: run a trial and keep the prompts the backend received."""

from __future__ import annotations

import pytest


def run_cell(scenario, arm: str, condition: str, index: int = 0, plugins=None):
    """Run trial ``index`` of one cell; return (result, steps, prompts sent to the scripted backend)."""
    from safeembodai_core.loop import run_trial
    from safeembodai_core.plugins import load_plugins
    from safeembodai_core.runner import ScenarioRunner, trial_spec

    plugins = plugins or load_plugins(environ={})
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, scenario.environments[0].key, arm, condition, index)
        parts = runner.parts(spec)
        result = run_trial(spec, parts, runner.settings(arm), plugins)
        return result, runner.state.steps(spec.trial_id), list(parts.backend.prompts)
    finally:
        runner.close()


@pytest.fixture
def cell():
    return run_cell
