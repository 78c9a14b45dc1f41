"""Collisions the robot causes itself in the static-obstacle room, with and without validation.

Issue 10's acceptance check: with safety validation on, the robot never drives into a static
obstacle (a ``self`` collision with a wall or a ball) in SO. Runs ``scenarios/so.yaml`` with the
offline mock pilot, both conditions (no attack, the paper's prompt injection), and prints per arm
and condition the trials, outcomes, ``self`` and ``struck`` collisions, and the rate of ``self``
collisions per 100 trials with a 95% Wilson interval.

    python bench/so_self_collisions.py [--trials 500] [--baseline-trials 100] [--workers 2]

``--trials`` is per condition for the ``safeembodai`` arm (500 x 2 conditions = the 1,000-trial
check); ``--baseline-trials`` per condition for the undefended arm, for contrast (0 to skip).
What it does not show: collisions with moving obstacles (SO has none), or any real LLM's behaviour
(the mock pilot's weaknesses are configured, docs/backends.md).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def run_arm(arm: str, trials: int, workers: int, seed: int, extra: list[str]):
    """Every trial of ``arm`` in both SO conditions; the results."""
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins()
    overrides = [f"trials={trials}", f"seed={seed}", "state=sqlite", *extra]
    scenario = load_scenario(str(REPO / "scenarios" / "so.yaml"), overrides, plugins.registry)
    scenario = scenario.model_copy(update={"arms": {arm: scenario.arms[arm]}})
    with tempfile.TemporaryDirectory() as root:
        ablation = Ablation(scenario, plugins, RunFolder(Path(root) / "run"), workers=workers)
        try:
            return ablation.run()
        finally:
            ablation.close()


def wilson(successes: int, n: int, z: float = 1.96) -> tuple[float, float]:
    if n == 0:
        return float("nan"), float("nan")
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * ((p * (1 - p) / n + z * z / (4 * n * n)) ** 0.5) / (1 + z * z / n)
    return max(0.0, centre - half), min(1.0, centre + half)


def describe(arm: str, results) -> list[str]:
    lines = []
    for condition in sorted({r.spec.condition for r in results}):
        cell = [r for r in results if r.spec.condition == condition]
        outcomes = Counter(r.outcome.value for r in cell)
        own = sum(r.collisions_self for r in cell)
        with_own = sum(1 for r in cell if r.collisions_self)
        struck = sum(r.collisions_struck for r in cell)
        low, high = wilson(with_own, len(cell))
        lines.append(
            f"{arm:12s} {condition:10s} trials {len(cell):5d}  self collisions {own:4d} "
            f"(in {with_own} trials: {100 * with_own / len(cell):.1f} per 100, "
            f"95% CI {100 * low:.1f}-{100 * high:.1f})  "
            f"struck {struck}  outcomes " + ", ".join(f"{k} {v}" for k, v in sorted(outcomes.items())))
    return lines


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=500, help="trials per condition, safeembodai arm")
    parser.add_argument("--baseline-trials", type=int, default=100, help="trials per condition, baseline arm")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()

    out = sys.stdout
    out.write("scenario so.yaml, backend mock (simulated pilot: not a measurement of an LLM)\n")
    for arm, trials in (("safeembodai", args.trials), ("baseline", args.baseline_trials)):
        if trials <= 0:
            continue
        started = time.perf_counter()
        results = run_arm(arm, trials, args.workers, args.seed, args.overrides)
        for line in describe(arm, results):
            out.write(line + "\n")
        out.write(f"{arm}: {len(results)} trials in {time.perf_counter() - started:.0f} s\n")


if __name__ == "__main__":
    main()
