"""What ROS 2 bags cost: writing them during a run, exporting them later, and guard-bag's speed.

1. The same trials run without and with ``--bags mcap`` (one process): seconds per trial and the ratio.
2. ``safeembodai export`` of those trials (a replay of the recorded answers, then the bag): seconds
   per trial, as a ratio to running the trial.
3. ``guard-bag`` on the exported bags: plans judged per second (``/safeembodai/plan`` with the
   recorded rules) and Twist commands per second (``/cmd_vel``, ``lidar_clearance``), and the bags'
   size per step.

    python bench/bags.py [--scenario scenarios/mo.yaml] [--trials 3]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def ablate(scenario, plugins, folder: Path, bags: str | None) -> tuple[float, list]:
    from safeembodai_core.ablation import Ablation, RunFolder

    ablation = Ablation(scenario, plugins, RunFolder(folder), bags=bags)
    try:
        started = time.perf_counter()
        results = ablation.run()
        return time.perf_counter() - started, results
    finally:
        ablation.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenario", default=str(REPO / "scenarios" / "mo.yaml"))
    parser.add_argument("--trials", type=int, default=3)
    args = parser.parse_args()

    from click.testing import CliRunner

    from safeembodai_core import Guard
    from safeembodai_core.cli import cli
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.guard.bag_guard import guard_bag
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins()
    scenario = load_scenario(args.scenario, [f"trials={args.trials}"], plugins.registry)
    with tempfile.TemporaryDirectory() as root:
        root = Path(root)
        ablate(scenario, plugins, root / "warm", None)  # imports and physics clients, once
        plain, results = ablate(scenario, plugins, root / "plain", None)
        recorded, _ = ablate(scenario, plugins, root / "bags", "mcap")
        n = len(results)
        steps = sum(r.steps for r in results)
        started = time.perf_counter()
        done = CliRunner().invoke(cli, ["export", str(root / "plain"), "--out", str(root / "exported")])
        exported = time.perf_counter() - started
        if done.exit_code != 0:
            raise SystemExit(f"export failed: {done.output} {done.exception}")
        bags = sorted(p for p in (root / "exported").iterdir() if p.is_dir())
        size = sum(f.stat().st_size for bag in bags for f in bag.iterdir())
        timings = {}
        for topic, rules in (("/safeembodai/plan", None), ("/cmd_vel", ["lidar_clearance"])):
            count, started = 0, time.perf_counter()
            for bag in bags:
                guard = Guard(rules, plugins=plugins) if rules else Guard(plugins=plugins)
                count += len(guard_bag(bag, guard, cmd_topic=topic, pose_topic="/pose", max_hold_s=60.0).verdicts)
            timings[topic] = (count, time.perf_counter() - started)
    print(f"{scenario.name}: {n} trials, {steps} steps")
    print(f"run without bags      {plain / n:7.3f} s/trial")
    print(f"run with --bags mcap  {recorded / n:7.3f} s/trial  (x{recorded / plain:.2f} of without)")
    print(f"export (replay+write) {exported / n:7.3f} s/trial  (x{exported / plain:.2f} of running the trial)")
    print(f"bag size              {size / steps / 1024:7.1f} KiB/step")
    for topic, (count, seconds) in timings.items():
        print(f"guard-bag {topic:18s} {count / seconds:8.0f} commands/s ({count} commands)")


if __name__ == "__main__":
    main()
