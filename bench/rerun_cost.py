"""What Rerun recordings cost (issue 38): writing them during a run, and ``view`` of a 40-trial run.

1. The same trials (``scenarios/mo.yaml``, 10 per cell = 40, the mock pilot, one process) run
   without and with recordings (``ablate --rerun``: each trial's ``.rrd`` written as it ends), after a
   warm-up run, ``--repeat`` times alternating. Printed: seconds per trial each way, the run's ratio,
   and per trial the time spent writing its recording (``rerun_export.recording_bytes``, timed) as a
   share of that trial's own wall time (bar: at most 15%).
2. ``safeembodai view RUN --out SITE`` of the 40-trial run with recordings, cold (no site yet), in a
   fresh process as a user runs it: seconds (bar: at most 20 s on 2 cores), then again unchanged;
   and the run without recordings, cold, for what the recordings add.

The machine's load (``os.getloadavg``) and cores are printed with the numbers.

    python bench/rerun_cost.py [--trials 10] [--repeat 2] [--set key=value ...]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def ablate(scenario, plugins, folder: Path, recordings: bool, writes: list[float]) -> tuple[float, list[float]]:
    """The run's seconds and each trial's own seconds (from the previous trial's end to its end)."""
    from safeembodai_core import rerun_export
    from safeembodai_core.ablation import Ablation, RunFolder

    real = rerun_export.recording_bytes

    def timed(*args, **kwargs):
        started = time.perf_counter()
        try:
            return real(*args, **kwargs)
        finally:
            writes.append(time.perf_counter() - started)

    rerun_export.recording_bytes = timed
    ends: list[float] = []
    try:
        ablation = Ablation(scenario, plugins, RunFolder(folder), recordings=recordings)
        try:
            started = time.perf_counter()
            ablation.run(lambda result: ends.append(time.perf_counter()))
            total = time.perf_counter() - started
        finally:
            ablation.close()
    finally:
        rerun_export.recording_bytes = real
    return total, [b - a for a, b in zip([started, *ends], ends)]


def view(run: Path, site: Path) -> float:
    started = time.perf_counter()
    subprocess.run([sys.executable, "-m", "safeembodai_core", "view", str(run), "--out", str(site)], check=True,
                   capture_output=True)
    return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=10, help="trials per cell (mo.yaml has 4 cells)")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()

    from safeembodai_core.plugins import load_plugins
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins()
    scenario = load_scenario(REPO / "scenarios" / "mo.yaml", [f"trials={args.trials}", *args.overrides],
                             plugins.registry)
    print(f"{os.cpu_count()} cores, load {os.getloadavg()[0]:.1f} at the start")
    with tempfile.TemporaryDirectory() as scratch:
        root = Path(scratch)
        warm = load_scenario(REPO / "scenarios" / "mo.yaml", ["trials=1"], plugins.registry)
        ablate(warm, plugins, root / "warm", True, [])  # imports, physics clients, rerun-sdk, once
        plain: list[float] = []
        recorded: list[float] = []
        shares: list[float] = []
        writes_all: list[float] = []
        trials_all: list[float] = []
        for round_ in range(args.repeat):
            total, _ = ablate(scenario, plugins, root / f"plain{round_}", False, [])
            plain.append(total)
            writes: list[float] = []
            total, trials = ablate(scenario, plugins, root / f"rrd{round_}", True, writes)
            recorded.append(total)
            assert len(writes) == len(trials), (len(writes), len(trials))
            shares += [w / t for w, t in zip(writes, trials)]
            writes_all += writes
            trials_all += trials
            n = len(trials)
            print(f"round {round_ + 1}: {n} trials; {plain[-1] / n:.3f} s per trial without recordings, "
                  f"{recorded[-1] / n:.3f} s with (x{recorded[-1] / plain[-1]:.2f}); load {os.getloadavg()[0]:.1f}")
        print(f"writing a trial's .rrd: median {statistics.median(writes_all) * 1000:.0f} ms, "
              f"mean {statistics.mean(writes_all) * 1000:.0f} ms")
        print(f"as a share of its trial's own time: median {statistics.median(shares):.1%}, "
              f"mean {statistics.mean(shares):.1%}, max {max(shares):.1%}; all writing / all trials' time "
          f"{sum(writes_all) / sum(trials_all):.1%} (bar: <= 15%)")
        print(f"whole run with recordings / without: x{statistics.median(recorded) / statistics.median(plain):.3f}")
        run = root / "rrd0"
        recordings = sorted((run / "recordings").glob("*.rrd"))
        size = sum(p.stat().st_size for p in recordings) / max(1, len(recordings)) / 1024
        print(f"{len(recordings)} recordings, {size:.0f} KiB each on average")
        cold = view(run, root / "site")
        again = view(run, root / "site")
        print(f"safeembodai view of the {len(recordings)}-trial run: cold {cold:.1f} s (bar: <= 20 s on 2 cores), "
              f"unchanged rebuild {again:.1f} s; load {os.getloadavg()[0]:.1f}")
        plain_view = view(root / "plain0", root / "site-plain")
        print(f"the same run without recordings: cold {plain_view:.1f} s; load {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main()
