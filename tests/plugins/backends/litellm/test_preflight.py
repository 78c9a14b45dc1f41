"""A backend that cannot work fails before the first trial, with one line, and leaves no folder."""

from __future__ import annotations

import types

import pytest
import yaml

from fake_openai import FakeOpenAI, Status
from safeembodai_core import hookimpl
from safeembodai_core.cli import main
from safeembodai_core.contracts.components import BackendReply
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.runs.runner import PreflightError, preflight
from safeembodai_core.scenario import parse_scenario
from safeembodai_core.testing import answer, turn


def scenario_file(tmp_path, url, **backend) -> str:
    data = {"name": "pre", "trials": 1, "max_steps": 2, "environments": ["flatland"],
            "backend": {"use": "gpt-4o", "options": {"api_base": url, "api_key_env": "SAFEEMBODAI_TEST_KEY",
                                                      "backoff_s": 0.0, "timeout_s": 5.0, "max_retries": 0, **backend}},
            "arms": {"baseline": {}}, "conditions": {"no_attack": {}}}
    path = tmp_path / "pre.yaml"
    path.write_text(yaml.safe_dump(data))
    return str(path)


def cli(capsys, *args) -> tuple[int, str]:
    with pytest.raises(SystemExit) as done:
        main(list(args))
    return done.value.code, capsys.readouterr().err


def one_error_line(stderr: str) -> str:
    """The one ``Error:`` line (warnings logged by failing trials may come before it)."""
    lines = [line for line in stderr.splitlines() if line.startswith("Error: ")]
    assert len(lines) == 1 and "Traceback" not in stderr, stderr
    return lines[0]


@pytest.fixture
def dead_url():
    """The URL of a server that was there a moment ago: nothing listens on its port now."""
    server = FakeOpenAI().start()
    url = server.url
    server.stop()
    return url


def test_a_server_that_is_down_stops_ablate_and_run_before_any_folder(tmp_path, capsys, fake_key, dead_url):
    scenario = scenario_file(tmp_path, dead_url)
    code, stderr = cli(capsys, "ablate", scenario, "--out", str(tmp_path / "runs"))
    line = one_error_line(stderr)
    assert code == 1 and "cannot reach 127.0.0.1:" in line and "nothing was run" in line
    assert stderr.strip() == line  # nothing else: no trial ran, nothing was logged
    assert not (tmp_path / "runs").exists()
    code, stderr = cli(capsys, "run", scenario, "--out", str(tmp_path / "one"))
    assert code == 1 and "cannot reach" in one_error_line(stderr) and not (tmp_path / "one").exists()


def test_a_missing_key_stops_ablate_before_any_folder(tmp_path, capsys, monkeypatch, fake_server):
    monkeypatch.delenv("SAFEEMBODAI_TEST_KEY", raising=False)
    code, stderr = cli(capsys, "ablate", scenario_file(tmp_path, fake_server.url), "--out", str(tmp_path / "runs"))
    line = one_error_line(stderr)
    assert code == 1 and "SAFEEMBODAI_TEST_KEY is not set" in line
    assert not (tmp_path / "runs").exists() and fake_server.requests == []


def test_a_reachable_server_passes_without_a_request(built_plugins, fake_server, fake_key, tmp_path):
    scenario = parse_scenario(open(scenario_file(tmp_path, fake_server.url)).read(), "pre.yaml",
                              registry=built_plugins.registry)
    preflight(scenario, built_plugins)
    assert fake_server.requests == []  # a TCP connection, no tokens spent


@pytest.mark.slow
def test_an_ablation_whose_every_trial_errs_exits_non_zero(tmp_path, capsys, fake_key, fake_server):
    fake_server.default = Status(401, "invalid api key")
    code, stderr = cli(capsys, "ablate", scenario_file(tmp_path, fake_server.url), "--out", str(tmp_path / "runs"))
    line = one_error_line(stderr)
    assert code == 1 and "every one of the 1 trials ended in error (1 backend)" in line and "--resume" in line
    (run,) = (tmp_path / "runs").iterdir()
    assert (run / "report.md").is_file()  # the report still says what happened


def test_backends_without_a_preflight_are_not_checked(tmp_path):
    class Bare:  # a third-party backend that does not subclass LLMBackend
        closed = False

        def complete(self, prompt, rng):
            return BackendReply(text=answer(turn(10)))

        def close(self):
            Bare.closed = True

    plugin = types.ModuleType("bare_backend")
    plugin.register_llm_backends = hookimpl(lambda register: register("bare", lambda options, context: Bare()))
    plugins = load_plugins([plugin], environ={})
    scenario = parse_scenario("name: b\nenvironments: [flatland]\nbackend: bare\n", "b.yaml", registry=plugins.registry)
    preflight(scenario, plugins)
    assert Bare.closed
    failing = types.ModuleType("failing_backend")

    class Down(Bare):
        def preflight(self):
            from safeembodai_core.errors import BackendError

            raise BackendError("llm backend 'down': the lab's server is off")

    failing.register_llm_backends = hookimpl(lambda register: register("down", lambda options, context: Down()))
    plugins = load_plugins([failing], environ={})
    scenario = parse_scenario("name: b\nenvironments: [flatland]\nbackend: down\n", "b.yaml", registry=plugins.registry)
    with pytest.raises(PreflightError, match="the lab's server is off"):
        preflight(scenario, plugins)
