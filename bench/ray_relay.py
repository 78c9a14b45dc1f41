"""What it costs that the coordinator writes a Ray run's folder (``ablation/relay.py``) instead of each
worker writing its own records, pictures and results into it.

Both designs run the same trials (``scenarios/mo.yaml``, the mock pilot, ``--workers 2``) on one
local Ray started once:

- **relay**: ``Ablation(..., executor="ray")``, as ``ablate --executor ray`` runs it: workers stream
  every step, result and picture, and the coordinator writes them;
- **direct**: the design before it, rebuilt here only: each actor runs the trial with the run
  folder's own store and writes it (which needs a disk every node shares), and returns the result.

Each run starts its actors, runs every trial and stops; the designs alternate, ``--repeat`` times each.
Printed: seconds per run, trials per second, and the relay's cost as a share of a trial's time
(the ratio of the medians, minus 1).

    python bench/ray_relay.py [--trials 4] [--repeat 3]
"""

from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def direct_run(scenario, plugins, folder: Path, workers: int) -> int:
    """The earlier design: actors write the run folder themselves."""
    import ray

    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.ablation.runner_pool import RunnerPool
    from safeembodai_core.models import TrialResult, TrialSpec

    @ray.remote
    class DirectWorker:
        def __init__(self, scenario_json, run_dir):
            self.pool = RunnerPool(scenario_json, run_dir, 1)

        def run(self, spec_json):
            return self.pool.run(TrialSpec.model_validate(spec_json)).model_dump(mode="json")

    ablation = Ablation(scenario, plugins, RunFolder(folder))  # the folder, its store and ledger: as ablate makes them
    try:
        scenario_json = scenario.model_dump(mode="json")
        actors = [DirectWorker.options(num_cpus=0).remote(scenario_json, str(folder)) for _ in range(workers)]
        pending = [spec.model_dump(mode="json") for spec in ablation.pending()]
        running, done = {}, 0
        while pending or running:
            for actor in actors:
                if pending and actor not in running.values():
                    running[actor.run.remote(pending.pop(0))] = actor
            ready, _ = ray.wait(list(running), num_returns=1)
            for ref in ready:
                del running[ref]
                result = TrialResult.model_validate(ray.get(ref))
                ablation.store.end_trial(result)  # as the coordinator did (idempotent)
                ablation.folder.note_finished([result.spec.trial_id])
                done += 1
        for actor in actors:
            ray.kill(actor)
    finally:
        ablation.close()
    return done


def relay_run(scenario, plugins, folder: Path, workers: int) -> int:
    from safeembodai_core.ablation import Ablation, RunFolder

    ablation = Ablation(scenario, plugins, RunFolder(folder), executor="ray", workers=workers)
    try:
        return len(ablation.run())
    finally:
        ablation.close()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=4, help="trials per cell (4 cells)")
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    import ray

    from safeembodai_core.logs import configure_logging
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    configure_logging("error")
    ray.init(address="local", include_dashboard=False, log_to_driver=False, configure_logging=False,
             _node_ip_address="127.0.0.1")
    plugins = load_plugins()
    scenario = load_scenario(REPO / "scenarios" / "mo.yaml", [f"trials={args.trials}"], plugins.registry)
    seconds: dict[str, list[float]] = {"direct": [], "relay": []}
    trials = 0
    with tempfile.TemporaryDirectory(prefix="bench-ray-relay-") as scratch:
        for k in range(args.repeat):
            for name, run in (("direct", direct_run), ("relay", relay_run)):
                start = time.perf_counter()
                trials = run(scenario, plugins, Path(scratch) / f"{name}-{k}", args.workers)
                seconds[name].append(time.perf_counter() - start)
    ray.shutdown()
    print(f"MO, mock pilot, {trials} trials, --workers {args.workers}, {args.repeat} runs each, local Ray, "
          f"{os.cpu_count()} cores")
    for name, values in seconds.items():
        median = statistics.median(values)
        print(f"{name:>6}: {median:6.2f} s per run (runs: {', '.join(f'{v:.2f}' for v in values)}), "
              f"{trials / median:.2f} trials/s")
    cost = statistics.median(seconds["relay"]) / statistics.median(seconds["direct"]) - 1
    print(f"relay vs direct: {cost:+.1%} of a trial's time (bar: at most +10%)")


if __name__ == "__main__":
    main()
