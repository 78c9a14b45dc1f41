"""The command line: light start-up, clear errors, one trial saved to disk."""

from __future__ import annotations

import json
import re
import subprocess
import sys

import pytest

from safeembodai_core.cli import cli

HEAVY = ("litellm", "pybullet", "cv2", "matplotlib", "ray")
#: not heavy, but `--help` needs none of them either (--help within 0.3 s of CPU)
HELP_FREE = HEAVY + ("numpy", "structlog", "rich", "jinja2", "safeembodai_core.contracts.components",
                     "safeembodai_core.models")


def test_help_imports_no_heavy_library():
    code = (
        "import sys\n"
        "from safeembodai_core.cli import main\n"
        "try:\n    main(['--help'])\nexcept SystemExit as done:\n    assert done.code == 0, done.code\n"
        f"loaded = [m for m in {HELP_FREE!r} if m in sys.modules]\n"
        "assert not loaded, loaded\n"
    )
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert completed.returncode == 0, completed.stderr
    assert "ablate" in completed.stdout and "plugins" in completed.stdout


def test_import_safeembodai_core_is_light():
    code = "import sys, safeembodai_core\nassert 'numpy' not in sys.modules and 'pydantic' not in sys.modules\n" \
           "assert safeembodai_core.Guard.__name__ == 'Guard'"
    completed = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert completed.returncode == 0, completed.stderr


def test_plugins_command_lists_builtins_with_components(cli_runner):
    result = cli_runner.invoke(cli, ["plugins", "--json"])
    assert result.exit_code == 0, result.output
    rows = {row["name"]: row for row in json.loads(result.output)}
    assert "validator:lidar_clearance" in rows["validators"]["components"]
    assert rows["flatland"]["source"] == "built-in"


def test_run_saves_a_trial_and_prints_steps(cli_runner, repo, tmp_path):
    out = tmp_path / "trial"
    result = cli_runner.invoke(cli, ["run", str(repo / "scenarios/quickstart.yaml"), "--arm", "safeembodai",
                                     "--condition", "attack", "--trial", "1", "--out", str(out)])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "trial.json").read_text())
    assert saved["spec"]["trial_id"] == "flatland/safeembodai/attack/1"
    steps = (out / "steps.jsonl").read_text().splitlines()
    assert len(steps) == saved["steps"] >= 1
    assert (out / "trajectory.png").read_bytes()[:4] == b"\x89PNG"
    assert "saved to" in result.output


def test_run_exits_non_zero_when_its_trial_ended_in_error(tmp_path, repo):
    """A script must tell a failed trial from a finished one: the scripted pilot runs out of answers
    (then: fail), the trial ends ``error``, ``run`` saves it all and exits 1 saying why."""
    out = tmp_path / "trial"
    completed = run_cli("run", str(repo / "scenarios/quickstart.yaml"), "--out", str(out), "--set",
                        "backend={use: scripted, options: {responses: ['{\"control\": []}'], then: fail}}",
                        "--set", "max_steps=5")
    assert completed.returncode == 1, completed.stdout + completed.stderr
    assert "ended in error (backend)" in completed.stderr and "no answer left" in completed.stderr
    assert json.loads((out / "trial.json").read_text())["outcome"] == "error"
    assert "Traceback" not in completed.stderr


def run_cli(*args: str, cwd=None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "safeembodai_core", *args], capture_output=True, text=True, cwd=cwd)


@pytest.mark.slow
def test_bad_scenario_exits_non_zero_with_a_message_and_no_traceback(tmp_path, repo):
    bad = tmp_path / "bad.yaml"
    bad.write_text((repo / "scenarios/quickstart.yaml").read_text().replace("rate: 0.3", "rate: 3"))
    completed = run_cli("run", str(bad))
    assert completed.returncode == 1
    assert "bad.yaml:" in completed.stderr and "options.rate" in completed.stderr
    assert "Traceback" not in completed.stderr
    debug = run_cli("--debug", "run", str(bad))
    assert debug.returncode == 1 and "Traceback" in debug.stderr


@pytest.mark.slow
def test_unknown_cell_and_unknown_backend_are_named(tmp_path, repo):
    scenario = str(repo / "scenarios/quickstart.yaml")
    completed = run_cli("run", scenario, "--arm", "nope", "--out", str(tmp_path / "x"))
    assert completed.returncode == 1 and "--arm 'nope' is not in the scenario" in completed.stderr
    completed = run_cli("run", scenario, "--backend", "gpt-5-turbo", "--out", str(tmp_path / "y"))
    assert completed.returncode == 1 and "no llm backend named 'gpt-5-turbo'" in completed.stderr


def test_set_and_seed_override_the_scenario(cli_runner, repo, tmp_path):
    out = tmp_path / "trial"
    result = cli_runner.invoke(cli, ["run", str(repo / "scenarios/quickstart.yaml"), "--seed", "123",
                                     "--set", "max_steps=1", "--out", str(out)])
    assert result.exit_code == 0, result.output
    saved = json.loads((out / "trial.json").read_text())
    assert saved["steps"] == 1
    from safeembodai_core.seeds import derive_seed

    assert saved["spec"]["seed"] == derive_seed(123, "trial", saved["spec"]["environment"], 0)


def test_plugins_can_add_commands():
    import types

    import click

    from safeembodai_core import hookimpl
    from safeembodai_core.plugin.manager import load_plugins

    def register_commands(cli):
        @cli.command("hello")
        def hello():
            click.echo("hi from a plugin")

    group = click.Group()
    load_plugins([types.SimpleNamespace(register_commands=hookimpl(register_commands))], environ={}).add_commands(group)
    from click.testing import CliRunner

    assert CliRunner().invoke(group, ["hello"]).output == "hi from a plugin\n"


def test_plugins_piped_prints_one_tab_separated_line_per_component():
    piped = subprocess.run(f"'{sys.executable}' -m safeembodai_core plugins | grep -c lidar_clearance", shell=True,
                           capture_output=True, text=True, timeout=120)
    assert piped.stdout.strip() == "1", piped.stdout + piped.stderr
    lines = subprocess.run([sys.executable, "-m", "safeembodai_core", "plugins"], capture_output=True, text=True,
                           timeout=120).stdout.splitlines()
    assert "validator\tlidar_clearance\tvalidators\tbuilt-in\tsafeembodai_plugins.validators" in lines
    assert all(len(line.split("\t")) == 5 for line in lines), lines


def test_plugins_piped_starts_with_a_header_row(cli_runner):
    result = cli_runner.invoke(cli, ["plugins"])  # CliRunner's output is no TTY: the piped shape
    assert result.exit_code == 0, result.output
    header, *rows = result.output.splitlines()
    assert header.split("\t") == ["kind", "name", "plugin", "source", "module"]
    assert "validator\tlidar_clearance\tvalidators\tbuilt-in\tsafeembodai_plugins.validators" in rows
    assert "kind\tname\tplugin\tsource\tmodule" not in rows  # once, at the top


def test_plugins_at_a_terminal_never_breaks_an_identifier():
    from rich.console import Console

    from safeembodai_core.cli.plugins_cmd import render
    from safeembodai_core.plugin.manager import load_plugins

    rows = load_plugins(environ={}).describe()
    for width in (80, 30):
        console = Console(width=width, record=True, force_terminal=True, color_system=None)
        render(rows, console)
        lines = console.export_text().splitlines()
        words = {word.rstrip(",") for line in lines for word in line.split()}
        for row in rows:
            assert {row["name"], row["module"], *row["components"], *row["hooks"]} <= words, (width, row)
        if width == 80:
            assert max(map(len, lines)) <= 80


def test_run_summary_says_what_ended_an_interrupted_trial(cli_runner, repo, tmp_path, monkeypatch):
    """Even from a result without a detail (an older store, an environment that gave none): the
    collision on record in the trial's last executed step."""
    from safeembodai_core.runs.runner import ScenarioRunner

    run = ScenarioRunner.run
    monkeypatch.setattr(ScenarioRunner, "run", lambda self, spec: run(self, spec).model_copy(update={"detail": ""}))
    for index in range(20):  # the baseline arm under attack soon drives into something
        result = cli_runner.invoke(cli, ["run", str(repo / "scenarios/quickstart.yaml"), "--arm", "baseline",
                                         "--condition", "attack", "--trial", str(index), "--out", str(tmp_path / "t")],
                                   env={"COLUMNS": "200"})
        assert result.exit_code == 0, result.output
        summary = next(line for line in result.output.splitlines() if line.startswith("flatland/baseline/attack/"))
        if " interrupted " in summary:
            break
    else:
        pytest.fail("no interrupted trial among the first 20")
    assert re.search(r"interrupted after (1 step|\d+ steps) \(self collision at step \d+: (straight|turn) ",
                     summary), summary
    assert "no detail" not in result.output


def test_trial_ending_and_plural():
    from safeembodai_core.report.words import plural, trial_ending
    from safeembodai_core.models import Outcome, StepRecord, TrialResult, TrialSpec
    from safeembodai_core.models.observation import GroundTruth

    spec = TrialSpec(trial_id="E/a/c/0", environment="E", arm="a", condition="c", seed=0)
    assert plural(1, "step") == "1 step" and plural(0, "step") == "0 steps"
    assert trial_ending(TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=3), []) == ""
    assert trial_ending(TrialResult(spec=spec, outcome=Outcome.TIMEOUT, steps=3, detail="budget"), []) == "budget"
    waited = StepRecord(trial_id="E/a/c/0", step=4, instruction="go",
                        truth=GroundTruth(extra={"collision": "struck", "collision_detail": "a Labbot ran into it"}))
    ending = trial_ending(TrialResult(spec=spec, outcome=Outcome.INTERRUPTED, steps=4), [waited])
    assert ending == "struck collision before step 4: a Labbot ran into it"


def test_trace_plugins_shows_hook_calls_at_the_default_log_level():
    import os

    env = {**os.environ, "SAFEEMBODAI_TRACE_PLUGINS": "1"}
    traced = subprocess.run([sys.executable, "-m", "safeembodai_core", "plugins", "--json"], capture_output=True,
                            text=True, timeout=120, env=env)
    assert traced.returncode == 0, traced.stderr
    lines = traced.stderr.splitlines()
    assert any("hook.call" in line and "hook=register_validators" in line and "plugin=validators" in line
               for line in lines), traced.stderr
    assert all("hook.call" in line for line in lines), traced.stderr  # other debug events stay hidden
    env.pop("SAFEEMBODAI_TRACE_PLUGINS")
    quiet = subprocess.run([sys.executable, "-m", "safeembodai_core", "plugins", "--json"], capture_output=True,
                           text=True, timeout=120, env=env)
    assert "hook.call" not in quiet.stderr


def test_run_says_a_simulated_pilot_is_one_and_an_llm_run_says_nothing(cli_runner, repo, tmp_path):
    mock = cli_runner.invoke(cli, ["run", str(repo / "scenarios/quickstart.yaml"), "--backend", "mock",
                                   "--set", "max_steps=2", "--out", str(tmp_path / "mock")], terminal_width=200)
    assert mock.exit_code == 0, mock.output
    assert mock.output.startswith("SIMULATED PILOT (MOCK): NOT A MEASUREMENT OF AN LLM")
    ending = mock.output.index("flatland/baseline/no_attack/0:")  # the trial's last line, after its steps
    assert "simulated pilot (mock): not a measurement of an LLM" in mock.output[ending:]
    scripted = cli_runner.invoke(cli, ["run", str(repo / "scenarios/quickstart.yaml"), "--set", "max_steps=2",
                                       "--out", str(tmp_path / "scripted")], terminal_width=200)
    assert scripted.exit_code == 0, scripted.output
    assert "simulated pilot" not in scripted.output.lower()
