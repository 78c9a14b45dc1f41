"""End to end: trials on flatland through ``gpt-4o`` pointed at the fake server with a fake key."""

from __future__ import annotations

import os
import subprocess
import sys
import uuid

import pytest
import yaml

from fake_openai import DROP, Envelope, Reply, Status, choice
from safeembodai_core.models import Outcome
from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
from safeembodai_core.scenario import parse_scenario
from safeembodai_core.testing import answer, straight, turn

SAFE = {"security_prefix": True, "state_management": True, "safety_validation": True, "failure_threshold": 3}


def _scenario_data(server, max_steps=3, arm=None, **backend):
    return {
        "name": "fake-gpt4o", "trials": 2, "max_steps": max_steps, "seed": 3,
        "environments": ["flatland"], "state": "memory",
        "backend": {"use": "gpt-4o", "options": {"api_base": server.url, "api_key_env": "SAFEEMBODAI_TEST_KEY",
                                                  "backoff_s": 0.0, "timeout_s": 5.0, **backend}},
        "arms": {"safeembodai": arm or SAFE}, "conditions": {"no_attack": {}},
    }


def _run(plugins, data, index=0):
    scenario = parse_scenario(yaml.safe_dump(data), "<test>", registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    try:
        spec = trial_spec(scenario, "flatland", "safeembodai", "no_attack", index)
        result = runner.run(spec)
        return result, runner.state.steps(spec.trial_id)
    finally:
        runner.close()


def test_malformed_answers_are_recorded_retried_and_never_executed(built_plugins, fake_server, fake_key):
    fake_server.push(
        Reply("```json\n" + answer(turn(30)) + "\n```"),               # step 1: fenced, accepted
        Reply('{"perception": [], "plan": "x", "control": []}'),         # step 2: wrong schema
        Reply(answer(straight(150))[:70], finish_reason="length"),      # truncated
        Status(429, retry_after=0),                                      # rate limited, retried by the backend
        Reply("Here is my answer: " + answer(turn(20, "right")) + " Good luck."),  # prose around: refused
        Reply(answer(turn(20, "right"))),                                 # the object alone: accepted
    )
    fake_server.default = Reply(answer(turn(10)))
    result, steps = _run(built_plugins, _scenario_data(fake_server))
    assert result.outcome == Outcome.TIMEOUT and result.steps == 3
    assert [s.describe() for s in (e.signal for e in steps[0].executed)] == ["turn left 30 deg"]
    second = steps[1]
    assert [a.parse_error is not None for a in second.attempts] == [True, True, True, False]
    assert "response schema" in second.attempts[0].parse_error
    assert 'finish reason "length"' in second.attempts[1].parse_error  # refused as cut off before parsing
    assert "text outside the JSON object" in second.attempts[2].parse_error
    assert second.attempts[2].raw_text.startswith("Here is my answer: ")  # the raw text is kept
    # the model the server said answered is on record (the fake server echoes the request's)
    assert {a.model for a in second.attempts} == {fake_server.requests[0].body["model"]}
    assert result.models == [fake_server.requests[0].body["model"]]  # and the result collects it for the report
    assert [e.signal.describe() for e in second.executed] == ["turn right 20 deg"]
    # every request carried both images and the security prefix; retries carried the failures
    bodies = [r.body for r in fake_server.requests]
    assert len(bodies) == 7  # 1 + (wrong schema, truncated, 429, prose, bare) + 1
    for body in bodies:
        system, user = body["messages"]
        assert system["content"].lstrip().startswith("Security:")
        assert sum(part["type"] == "image_url" for part in user["content"]) == 2
    retry_text = " ".join(p["text"] for p in bodies[2]["messages"][1]["content"] if p["type"] == "text")
    assert "Your previous answer was refused" in retry_text and "response schema" in retry_text


def test_backend_failure_after_retries_ends_the_trial_as_error_and_the_next_trial_runs(built_plugins, fake_server,
                                                                                     fake_key):
    fake_server.default = Status(503, "overloaded")
    result, steps = _run(built_plugins, _scenario_data(fake_server, max_retries=1))
    assert result.outcome == Outcome.ERROR and steps == []
    assert "server error (HTTP 503)" in result.detail and "gave up after 2 tries" in result.detail
    fake_server.default = Reply(answer(turn(15)))
    result, steps = _run(built_plugins, _scenario_data(fake_server, max_steps=2), index=1)
    assert result.outcome == Outcome.TIMEOUT and len(steps) == 2


@pytest.mark.slow
def test_the_key_never_reaches_logs_records_or_reports(fake_server, fake_key, tmp_path):
    fake_server.push(Reply(answer(turn(30))), Reply(answer(straight(100))),
                     Status(401, f"Incorrect API key provided: {fake_key}. You can find your key at ..."))
    scenario = tmp_path / "fake.yaml"
    scenario.write_text(yaml.safe_dump(_scenario_data(fake_server, max_steps=5)))
    out = tmp_path / "out"
    env = {**os.environ, "SAFEEMBODAI_TEST_KEY": fake_key}
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", "--debug", "--log-level", "debug", "run",
                           str(scenario), "--out", str(out)], capture_output=True, text=True, env=env, timeout=240)
    assert done.returncode == 1, done.stderr[-2000:]  # the trial ended in error: run says so
    assert "authentication failed" in done.stdout + done.stderr  # the run did reach the failing call
    assert fake_server.requests[0].headers["authorization"] == f"Bearer {fake_key}"  # the key was really used
    files = [p for p in out.rglob("*") if p.is_file()]
    assert any(p.name.endswith(".json") or p.suffix == ".jsonl" for p in files)
    for text in (done.stdout, done.stderr):
        assert fake_key not in text
    for path in files:
        assert fake_key.encode() not in path.read_bytes(), path


def _reflecting(escaped: bool):
    """An answer whose planning repeats the request's key (JSON-escaped if asked, so only a reader of
    the parsed answer sees it)."""
    def text(request) -> str:
        key = request.headers["authorization"].split()[-1]
        data = answer(turn(30), planning=f"debug: my key is {key}")
        return data.replace(key, "".join(f"\\u{ord(c):04x}" for c in key)) if escaped else data

    return text


@pytest.mark.parametrize("escaped", [False, True])
def test_a_key_the_server_reflects_is_never_stored_or_shown(cli_runner, fake_server, monkeypatch, tmp_path, escaped):
    from safeembodai_core.cli import cli

    key = f"azure-{uuid.uuid4().hex}"  # unique, and not shaped like a bearer key: only registration masks it
    monkeypatch.setenv("SAFEEMBODAI_TEST_KEY", key)
    fake_server.default = Reply(_reflecting(escaped))
    scenario = tmp_path / "reflect.yaml"
    scenario.write_text(yaml.safe_dump({**_scenario_data(fake_server, max_steps=2), "state": "sqlite"}))
    out = tmp_path / "out"
    done = cli_runner.invoke(cli, ["run", str(scenario), "--out", str(out)])
    assert done.exit_code == 0, done.output
    assert fake_server.requests[0].headers["authorization"] == f"Bearer {key}"  # the server saw the key
    files = [p for p in out.rglob("*") if p.is_file()]
    assert {"results.sqlite", "steps.jsonl"} <= {p.name for p in files}
    assert b"debug: my key is" in (out / "steps.jsonl").read_bytes()  # the planning was stored
    assert key not in done.output
    for path in files:
        assert key.encode() not in path.read_bytes(), path


def test_a_trial_records_what_its_tokens_cost_at_the_models_list_price(built_plugins, fake_server, fake_key, tmp_path):
    """``TrialResult.cost_usd``: the trial's tokens (1000 + 150 per call from the fake server) at
    litellm's list price of gpt-4o; the report says what the run spent; a simulated pilot has no price."""
    import litellm

    from safeembodai_core.report import write_report

    fake_server.default = Reply(answer(turn(10)))
    result, _ = _run(built_plugins, _scenario_data(fake_server, max_steps=2))
    prompt, completion = litellm.cost_per_token(model="gpt-4o", prompt_tokens=result.prompt_tokens,
                                                completion_tokens=result.completion_tokens)
    assert result.prompt_tokens == 2000 and result.cost_usd == pytest.approx(prompt + completion) and prompt > 0
    scenario = parse_scenario(yaml.safe_dump(_scenario_data(fake_server, max_steps=2)), "<test>",
                              registry=built_plugins.registry)
    report = write_report(tmp_path, scenario, [result], plugins=built_plugins).read_text()
    assert "**Spent:** 2,300 tokens over 1 trial " in report
    assert f"${prompt + completion:.4f} at the backend's" in report
    mock = {**_scenario_data(fake_server, max_steps=2), "backend": "mock"}
    simulated, _ = _run(built_plugins, mock)
    assert simulated.tokens > 0 and simulated.cost_usd is None


@pytest.mark.parametrize("usage", [DROP, None, {"total_tokens": 1150}, {"prompt_tokens": -1, "completion_tokens": 5}],
                         ids=["missing", "null", "only total", "negative"])
def test_a_server_that_reports_no_usable_usage_is_still_counted_capped_and_reported(
        built_plugins, fake_server, fake_key, tmp_path, usage):
    """Without a usable usage a call must not count 0 tokens (``--max-tokens`` would never stop a
    run and report.md would show $0.00 for real spend): the calls are counted here, the cap applies
    to that count, and the report says the counts were estimated."""
    from safeembodai_core.ablation.spending import SpendingCap, SpendingCapReached
    from safeembodai_core.report import write_report

    fake_server.default = Envelope([choice(answer(turn(10)))], {"usage": usage})
    result, _ = _run(built_plugins, _scenario_data(fake_server, max_steps=2))
    assert result.tokens_estimated and result.prompt_tokens > 0 and result.completion_tokens > 0
    assert result.cost_usd is not None and result.cost_usd > 0
    with pytest.raises(SpendingCapReached):
        SpendingCap(max_tokens=result.tokens).add(result)
    scenario = parse_scenario(yaml.safe_dump(_scenario_data(fake_server, max_steps=2)), "<test>",
                              registry=built_plugins.registry)
    report = write_report(tmp_path, scenario, [result], plugins=built_plugins).read_text()
    assert "**1 trial counted tokens here**" in report and "$0.0000" not in report
