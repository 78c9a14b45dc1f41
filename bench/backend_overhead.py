"""What the framework adds around one LLM call, how fast the mock pilot runs, and its calibration.

Run: ``python bench/backend_overhead.py [--calls 50] [--trials 10]``. Prints milliseconds per call
(median over ``--calls``, one process, against a fake OpenAI-compatible server on 127.0.0.1
with keep-alive and Nagle off):

* raw HTTP: one keep-alive POST of the very request body litellm sends, with ``http.client``;
* litellm call: ``gpt-4o`` backend ``complete()`` (litellm + openai SDK + our retry wrapper);
* framework: perception (camera PNG + LiDAR picture drawn and encoded), prompt building, parsing
  and validating the answer -- everything of Algorithm 1 except the call itself;
* the reading: the answer text alone (``parse_response``) against the whole reply -- the server's
  body read strictly (``reply_from_chat_completion``), a reasoning block, then ``read_reply`` --
  and building a ``gpt-4o`` backend (its own recording openai client), once per trial;

then the ratios framework / raw HTTP and (framework + litellm) / raw HTTP, and the mock pilot's
steps per second on flatland (a whole control step each: world, perception, prompt, mock,
parsing, validation, state), with token counting by litellm and by estimate.

``python bench/backend_overhead.py calibrate [--env OF] [--trials 40]`` runs the default
baseline/safeembodai x no_attack/attack cells with the mock pilot and prints the paper's
metrics per cell (the numbers quoted in ``docs/evidence/backends.md``). Numbers, never asserts.
"""

from __future__ import annotations

import argparse
import http.client
import json
import os
import statistics
import sys
import time
from pathlib import Path
from urllib.parse import urlparse

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "backends"))

from fake_openai import FakeOpenAI, Reply  # noqa: E402

from safeembodai_core.logs import configure_logging  # noqa: E402
from safeembodai_core.models import PromptRequest, parse_response, read_reply  # noqa: E402
from safeembodai_core.models.chat_completion import reply_from_chat_completion  # noqa: E402
from safeembodai_core.plugin.manager import load_plugins  # noqa: E402
from safeembodai_core.runs.runner import ScenarioRunner  # noqa: E402
from safeembodai_core.scenario import parse_scenario  # noqa: E402
from safeembodai_core.testing import answer, straight, turn  # noqa: E402
from safeembodai_core.validation.context import ValidationContext, validate_plan  # noqa: E402

ANSWER = answer(turn(20), straight(250))


def median_ms(fn, calls: int) -> float:
    samples = []
    for _ in range(calls):
        started = time.perf_counter()
        fn()
        samples.append((time.perf_counter() - started) * 1000)
    return statistics.median(samples)


def overhead(calls: int) -> None:
    plugins = load_plugins(environ={})
    registry = plugins.registry
    world = registry.build("environment", "flatland", {"obstacles": 4})
    observation = world.reset(0)
    perception = registry.build("perception", "images", {})
    builder = registry.build("prompt_builder", "jinja", {})
    validators = [(n, registry.build("validator", n, {})) for n in ("command_limits", "lidar_clearance")]
    context = ValidationContext(scan=observation.lidar, robot=world.robot)
    prompt = None

    def framework() -> None:
        nonlocal prompt
        modalities = perception.perceive(observation)
        prompt = builder.build(PromptRequest(instruction="Find the red can.", modalities=modalities, step=2,
                                             security_prefix="paper"))
        validate_plan(parse_response(ANSWER).control, context, validators)

    framework_ms = median_ms(framework, calls)
    os.environ["SAFEEMBODAI_BENCH_KEY"] = "sk-bench-not-a-real-key"
    with FakeOpenAI(Reply(ANSWER)) as server:
        backend = registry.build("llm_backend", "gpt-4o", {"api_base": server.url,
                                                           "api_key_env": "SAFEEMBODAI_BENCH_KEY"})
        rng = np.random.default_rng(0)
        backend.complete(prompt, rng)  # warm up: client construction, first connection
        litellm_ms = median_ms(lambda: backend.complete(prompt, rng), calls)
        body = json.dumps(server.requests[-1].body).encode()
        target = urlparse(server.url)
        connection = http.client.HTTPConnection(target.hostname, target.port)

        def raw() -> None:
            connection.request("POST", target.path + "/chat/completions", body,
                               {"Content-Type": "application/json", "Authorization": "Bearer sk-bench"})
            connection.getresponse().read()

        raw()
        raw_ms = median_ms(raw, calls)
        connection.close()
    size_kb = len(body) / 1024
    print(f"request body: {size_kb:.0f} KB (two PNGs as base64)")
    print(f"raw HTTP round trip:          {raw_ms:8.2f} ms")
    print(f"litellm call (gpt-4o backend): {litellm_ms:7.2f} ms  (litellm adds {litellm_ms - raw_ms:.2f} ms)")
    print(f"framework around the call:    {framework_ms:8.2f} ms  (perceive + build + parse + validate)")
    print(f"ratio framework / raw HTTP:   {framework_ms / raw_ms:8.1f}x")
    print(f"ratio (framework + litellm) / raw HTTP: {(framework_ms + litellm_ms) / raw_ms:.1f}x")
    reading(calls, registry)


def reading(calls: int, registry) -> None:
    """The strict reading of the answer text alone and of the whole reply; building a backend."""
    content = f"<think>Turn towards the can, then drive on.</think>\n{ANSWER}"
    body = json.dumps({"id": "c", "object": "chat.completion", "created": 0, "model": "m",
                       "choices": [{"index": 0, "message": {"role": "assistant", "content": content,
                                                            "reasoning_content": "short thought"},
                                    "finish_reason": "stop"}],
                       "usage": {"prompt_tokens": 1000, "completion_tokens": 150}})
    text_ms = median_ms(lambda: parse_response(ANSWER), calls * 10)
    whole_ms = median_ms(lambda: read_reply(reply_from_chat_completion(body)), calls * 10)
    print(f"reading the answer text alone:  {text_ms:8.3f} ms")
    print(f"reading the whole reply:        {whole_ms:8.3f} ms  (envelope + reasoning + text: "
          f"{whole_ms / text_ms:.1f}x the text alone)")
    options = {"api_base": "http://127.0.0.1:9/v1", "api_key_env": "SAFEEMBODAI_BENCH_KEY"}
    build_ms = median_ms(lambda: registry.build("llm_backend", "gpt-4o", options).close(), max(5, calls // 5))
    print(f"building a gpt-4o backend:      {build_ms:8.2f} ms  (once per trial: its recording openai client)")


def _scenario(plugins, env: str, trials: int, counting: str, conditions: dict | None = None):
    environment = {"use": "flatland", "options": {"obstacles": 4}} if env == "flatland-so" else env
    data = {"name": "bench", "trials": trials, "max_steps": 20, "environments": [environment], "state": "memory",
            "backend": {"use": "mock", "options": {"token_counting": counting}}}
    if conditions is not None:
        data["conditions"] = conditions
    return parse_scenario(yaml.safe_dump(data), "<bench>", registry=plugins.registry)


def mock_speed(trials: int) -> None:
    plugins = load_plugins(environ={})
    for counting in ("litellm", "estimate"):
        runner = ScenarioRunner(_scenario(plugins, "flatland", trials, counting, {"no_attack": {}}), plugins)
        runner.run(runner.specs()[0])  # warm up (litellm import, first world)
        started, steps = time.perf_counter(), 0
        for spec in runner.specs():
            steps += runner.run(spec).steps
        elapsed = time.perf_counter() - started
        runner.close()
        print(f"mock pilot on flatland, token_counting={counting:8s}: {steps / elapsed:6.1f} steps/s "
              f"({steps} steps)")


#: the paper's attack (its six prompts, docs/attacks.md) at the authors' release rate, 0.5
PAPER_CONDITIONS = {"no_attack": {}, "attack": {"attackers": [{"use": "prompt_injection",
                                                               "options": {"rate": 0.5, "kinds": "paper"}}]}}


def calibrate(env: str, trials: int) -> None:
    from safeembodai_core.metrics import paper_metrics

    plugins = load_plugins(environ={})
    runner = ScenarioRunner(_scenario(plugins, env, trials, "litellm", PAPER_CONDITIONS), plugins)
    cells: dict[tuple[str, str], list] = {}
    for spec in runner.specs():
        cells.setdefault((spec.arm, spec.condition), []).append(runner.run(spec))
    runner.close()
    print(f"mock pilot, default options, {env}, {trials} trials per cell, 20-step budget, "
          "attack: the paper's six prompts at rate 0.5")
    for (arm, condition), results in cells.items():
        m = paper_metrics.cell_metrics(results, budget=20)
        attacked = sum(r.attacked_steps for r in results)
        per_attack = sum(r.flagged_steps for r in results) / attacked if attacked else 0.0
        tokens = sum(r.tokens for r in results) / max(1, sum(r.steps for r in results))
        print(f"{arm:12s} {condition:10s} MOER {m.moer.value:.2f}  ADR {m.adr.value:.2f} "
              f"(flagged/attacked {per_attack:.2f})  steps(completed) {m.steps.value:.1f}  "
              f"tokens/step {tokens:.0f}  outcomes {dict((k, v) for k, v in m.outcomes.items() if v)}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("mode", nargs="?", choices=("overhead", "calibrate"), default="overhead")
    parser.add_argument("--calls", type=int, default=50)
    parser.add_argument("--trials", type=int, default=10)
    parser.add_argument("--env", default="OF", help="calibrate: OF, SO, DO, MO, flatland or flatland-so")
    args = parser.parse_args()
    configure_logging("error")
    if args.mode == "calibrate":
        calibrate(args.env, args.trials)
        return
    overhead(args.calls)
    mock_speed(args.trials)


if __name__ == "__main__":
    main()
