"""What a trial's capture (bags, Rerun recordings, replays) wraps around the environment."""

from __future__ import annotations

import inspect

import pytest

from safeembodai_core.contracts.components import Environment
from safeembodai_core.loop.capture import TrialCapture
from safeembodai_core.testing import CorridorWorld


def test_the_capturing_environment_passes_every_environment_method_on():
    wrapped, _ = TrialCapture().wrap(CorridorWorld(), None)  # type: ignore[arg-type]
    methods = [name for name, _ in inspect.getmembers(Environment, inspect.isfunction) if not name.startswith("_")]
    assert "another_call" in methods
    assert [name for name in methods if name not in vars(type(wrapped))] == []


def test_a_retry_reaches_the_captured_world():
    calls = []

    class Room(CorridorWorld):
        def another_call(self) -> None:
            calls.append("retry")

    wrapped, _ = TrialCapture().wrap(Room(), None)  # type: ignore[arg-type]
    wrapped.another_call()
    assert calls == ["retry"]


@pytest.mark.slow
def test_a_trial_with_every_retry_charged_replays_on_the_same_clock(repo):
    """A room with think_time_per_call, replayed for export: each retry is charged there too."""
    from safeembodai_core.loop.replay import replay_trial
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins(environ={})
    scenario = load_scenario(repo / "scenarios" / "movers.yaml",
                             ["trials=4", "state=memory", "max_steps=8",
                              "environments.0.options.think_time_per_call=true"], plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, "DO", "moving", "no_attack", 2)
        runner.run(spec)
        records = runner.state.steps(spec.trial_id)
        assert any(len(record.attempts) > 1 for record in records)  # retries were charged
        _, replayed, _ = replay_trial(runner, spec, records)
        assert [r.sim_time_s for r in replayed] == pytest.approx([r.sim_time_s for r in records])
    finally:
        runner.close()
