"""``safeembodai report`` at the terminal: a stored name's control characters are shown as escapes,
on stdout and in whatever a library prints while the figures are drawn."""

from __future__ import annotations

import warnings

from safeembodai_core.cli import cli


def test_a_stored_arm_names_escape_never_reaches_the_terminal_raw(cli_runner, repo, plugins, tmp_path):
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.scenario import load_scenario

    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=2"], plugins.registry)
    hostile = "arm\x1b[2J"
    arms = {(hostile if name == "baseline" else name): arm for name, arm in scenario.arms.items()}
    scenario = scenario.model_copy(update={"arms": arms})
    folder = RunFolder.create(tmp_path / "runs", scenario)
    ablation = Ablation(scenario, plugins, folder)
    try:
        ablation.run()
    finally:
        ablation.close()
    with warnings.catch_warnings(record=True) as printed:  # what the terminal would have shown
        warnings.simplefilter("always")
        result = cli_runner.invoke(cli, ["report", str(folder.path)])
    assert result.exit_code == 0, result.output
    assert "arm\\x1b[2J" in result.output
    shown = result.output + "".join(str(warning.message) for warning in printed)
    assert "\x1b" not in shown
