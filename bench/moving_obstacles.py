"""What ``moving_obstacles`` costs: microseconds per check, and its effect on collisions, MOER and steps.

``python bench/moving_obstacles.py micro [--repeats 300]`` times one ``validate`` call per rule on
real pybullet ``DO`` scans (two readings 5 s apart, three Labbots, a plan of three straights):
``lidar_clearance``, ``footprint_sweep``, and ``moving_obstacles`` for the plan's first signal
(finding the movers in the two scans, then the check) and for a later signal (the movers are
cached per scan; the check only). Median and 90th percentile, microseconds, one process.

``python bench/moving_obstacles.py ablation RUN [RUN ...]`` reads run folders of
``safeembodai ablate scenarios/dynamic.yaml`` (``--set trials=N``; several runs with other
``--seed`` values pool) and prints per room, arm and
condition: trials, outcomes, trials with a ``self`` collision into a Labbot (rate per 100 with a
95% Wilson interval), ``struck`` collisions, completed share (Wilson interval), MOER (its
bootstrap interval) and mean steps of completed trials; then, per room, how each arm's ``self``
rate and completed share compare with ``clearance`` (V(C) alone), pooled over both conditions,
against the issue's bar (``self`` down by >= 80 %, completed down by <= 5 points). Numbers only,
never asserts. The pilot is the offline mock: not a measurement of an LLM.
"""

from __future__ import annotations

import argparse
import json
import sqlite3
import statistics
import sys
import time
from collections import Counter
from pathlib import Path


def micro(repeats: int) -> None:
    from safeembodai_core.models import Straight
    from safeembodai_core.plugins import load_plugins
    from safeembodai_core.validation import PastScan, ValidationContext

    plugins = load_plugins(environ={})
    env = plugins.registry.build("environment", "DO", {"think_time_s": 5, "labbots": 3})
    try:
        first = env.reset(3)
        second = env.observe()  # no command came: the think time passed, the Labbots moved
    finally:
        env.close()
    context = ValidationContext(scan=second.lidar, robot=env.robot, start_pose=second.pose,
                                sim_time_s=second.sim_time_s,
                                history=(PastScan(first.lidar, first.pose, first.sim_time_s),))
    go = Straight(command="straight", direction="forward", distance=300)
    later = context.advanced(go).advanced(go)
    rules = {name: plugins.registry.build("validator", name, options)
             for name, options in (("lidar_clearance", {}), ("footprint_sweep", {}),
                                   ("moving_obstacles", {"think_time_s": 5}))}
    mover = rules["moving_obstacles"]
    print(f"DO seed 3, {second.lidar.beam_count} beams, movers found: {len(mover.movers(context)[0])}; "
          f"median / p90 microseconds per validate(), {repeats} repeats")
    cases = [("lidar_clearance", rules["lidar_clearance"], context, False),
             ("footprint_sweep", rules["footprint_sweep"], context, False),
             ("moving_obstacles, first signal (find movers + check)", mover, context, True),
             ("moving_obstacles, later signal (check only)", mover, later, False)]
    for label, rule, ctx, fresh in cases:
        times = []
        for _ in range(repeats):
            if fresh:
                rule._cache = None
            started = time.perf_counter()
            rule.validate(go, ctx)
            times.append((time.perf_counter() - started) * 1e6)
        times.sort()
        print(f"  {label:55s} {statistics.median(times):8.0f} {times[int(0.9 * len(times))]:8.0f}")


def _results(runs: list[Path]):
    """Every finished trial of the runs (runs of the same scenario with other seeds pool)."""
    from safeembodai_core.models import TrialResult

    results = []
    for run in runs:
        database = run / "results.sqlite" if run.is_dir() else run
        with sqlite3.connect(f"file:{database}?mode=ro", uri=True) as connection:
            rows = connection.execute("SELECT result FROM trials WHERE result IS NOT NULL").fetchall()
        results.extend(TrialResult.model_validate(json.loads(row[0])) for row in rows)
    return results


def _labbot_self(result) -> bool:
    return result.collisions_self > 0 and "Labbot" in result.detail


def ablation(runs: list[Path]) -> None:
    from safeembodai_core.metrics import cell_metrics, group_by_cell, wilson

    results = _results(runs)
    cells = group_by_cell(results)
    print(f"runs {', '.join(map(str, runs))}: {len(results)} trials (backend mock: simulated pilot, not a measurement of an LLM)")
    print("room arm        condition     n  self->Labbot/100 [95% CI]  struck  done [95% CI]       MOER [95% CI]      "
          "steps*  outcomes")
    for (room, arm, condition), cell in sorted(cells.items()):
        n = len(cell)
        own = sum(_labbot_self(r) for r in cell)
        rate = wilson(own, n)
        done = wilson(sum(r.outcome.value == "completed" for r in cell), n)
        metrics = cell_metrics(cell, budget=25, attacked=condition != "no_attack")
        steps = [r.steps for r in cell if r.outcome.value == "completed"]
        outcomes = ", ".join(f"{k} {v}" for k, v in sorted(Counter(r.outcome.value for r in cell).items()))
        print(f"{room:4s} {arm:10s} {condition:10s} {n:5d}  {100 * own / n:5.1f} [{100 * rate.low:4.1f}-{100 * rate.high:4.1f}]"
              f"     {sum(r.collisions_struck for r in cell):5d}  {done.value:.2f} [{done.low:.2f}-{done.high:.2f}]"
              f"  {metrics.moer.value:.2f} [{metrics.moer.low:.2f}-{metrics.moer.high:.2f}]"
              f"  {statistics.mean(steps) if steps else float('nan'):5.1f}  {outcomes}")
    print("\npooled over conditions, against clearance (V(C) alone):")
    for room in sorted({key[0] for key in cells}):
        pooled: dict[str, list] = {}
        for (r, arm, _), cell in cells.items():
            if r == room:
                pooled.setdefault(arm, []).extend(cell)
        base = pooled.get("clearance")
        if not base:
            continue
        base_self = sum(_labbot_self(r) for r in base) / len(base)
        base_done = sum(r.outcome.value == "completed" for r in base) / len(base)
        for arm, cell in sorted(pooled.items()):
            own = sum(_labbot_self(r) for r in cell) / len(cell)
            done = sum(r.outcome.value == "completed" for r in cell) / len(cell)
            cut = 1 - own / base_self if base_self else float("nan")
            print(f"  {room} {arm:10s} n={len(cell):5d}  self->Labbot {100 * own:5.1f}/100 ({100 * cut:+.0f}% cut vs "
                  f"{100 * base_self:.1f})  completed {done:.3f} ({100 * (done - base_done):+.1f} points)  "
                  f"bar met: {cut >= 0.8 and done - base_done >= -0.05}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    timing = commands.add_parser("micro", help="microseconds per check")
    timing.add_argument("--repeats", type=int, default=300)
    read = commands.add_parser("ablation", help="read a run folder of scenarios/dynamic.yaml")
    read.add_argument("runs", type=Path, nargs="+", help="run folders (or results.sqlite files); pooled")
    args = parser.parse_args()
    if args.command == "micro":
        micro(args.repeats)
    else:
        ablation(args.runs)


if __name__ == "__main__":
    sys.exit(main())
