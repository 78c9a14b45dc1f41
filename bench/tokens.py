"""Tokens per step for each arm, counted as gpt-4o would bill them (both QVGA images included).

Runs the scenario's trials with the mock pilot, whose usage is counted with litellm's gpt-4o
tokenizer (images at low detail: 85 tokens each), and prints prompt + completion tokens per LLM
call and per step for every arm and condition, against the paper's ~1,213 tokens per step (10,918 / 9) for
SafeEmbodAI (Figure 8: 10,918 tokens over 9 steps in OF) and the target of <= 1,000.

    python bench/tokens.py [SCENARIO] [--trials 3] [--set key=value ...]

Defaults to scenarios/components.yaml restricted to OF (one arm per defence).
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
PAPER_PER_STEP = 10918 / 9
TARGET = 1000


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", nargs="?", default=str(REPO / "scenarios" / "components.yaml"))
    parser.add_argument("--trials", type=int, default=3)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()

    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.runs.runner import ScenarioRunner
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins()
    overrides = [f"trials={args.trials}", "state=memory", "environments=[OF]", *args.overrides]
    scenario = load_scenario(args.scenario, overrides, plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    totals: dict[tuple[str, str], list[int]] = defaultdict(lambda: [0, 0, 0, 0])  # prompt, completion, calls, steps
    try:
        for spec in runner.specs():
            runner.run(spec)
            for record in runner.state.steps(spec.trial_id):
                row = totals[(spec.arm, spec.condition)]
                for attempt in record.attempts:
                    row[0] += attempt.usage.prompt_tokens
                    row[1] += attempt.usage.completion_tokens
                    row[2] += 1
                row[3] += 1
    finally:
        runner.close()
    out = sys.stdout
    out.write(f"{scenario.name} on OF, {scenario.trials} trials per cell, backend {scenario.backend.use}\n")
    out.write(f"{'arm':18} {'condition':10} {'prompt/call':>11} {'compl/call':>10} {'per call':>8} {'per step':>8} "
              f"{'x paper':>7} {'target':>6}\n")
    for (arm, condition), (prompt, completion, calls, steps) in sorted(totals.items()):
        per_call = (prompt + completion) / calls
        per_step = (prompt + completion) / steps
        verdict = "ok" if per_step <= TARGET else "over"
        out.write(f"{arm:18} {condition:10} {prompt / calls:11.0f} {completion / calls:10.0f} {per_call:8.0f} "
                  f"{per_step:8.0f} {per_step / PAPER_PER_STEP:7.2f} {verdict:>6}\n")
    out.write(f"paper: ~{PAPER_PER_STEP:.0f} tokens per step (SafeEmbodAI, OF); target <= {TARGET} per step\n")


if __name__ == "__main__":
    main()
