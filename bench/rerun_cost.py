"""What Rerun recordings cost (issue 38): writing them during a run, and ``view`` of a 40-trial run.

1. The same trials (``scenarios/mo.yaml``, 10 per cell = 40, the mock pilot, one process) run
   without and with recordings (``ablate --rerun``: each trial's ``.rrd`` written as it ends), after a
   warm-up run, ``--repeat`` times alternating. Printed: seconds per trial each way, the run's ratio,
   and per trial the time spent writing its recording (``rerun_export.recording_bytes``, timed) as a
   share of that trial's own wall time (bar: at most 15%).
2. ``safeembodai view RUN --out SITE`` of the 40-trial run with recordings, cold (no site yet), in a
   fresh process as a user runs it: seconds (bar: at most 20 s on 2 cores), the site's size and the
   ratio to that run's own time (issue 50), then again unchanged; the same build in one process (no
   helper process); and the run without recordings, cold, for what the recordings add.

The machine's load (``os.getloadavg``) and cores are printed with the numbers.

    python bench/rerun_cost.py [--trials 10] [--repeat 2] [--set key=value ...]
"""

from __future__ import annotations

import argparse
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def ablate(scenario, plugins, folder: Path, recordings: bool, writes: list[tuple[float, float]]
           ) -> tuple[float, list[tuple[float, float]]]:
    """The run's seconds and each trial's own (wall, CPU) seconds (from the previous trial's end to its
    end; CPU: this process's, every thread's); ``writes`` gets each recording's (wall, CPU) seconds."""
    from safeembodai_core.runs import rerun_recording as rerun_export
    from safeembodai_core.ablation import Ablation, RunFolder

    real = rerun_export.recording_bytes

    def timed(*args, **kwargs):
        started, cpu = time.perf_counter(), time.process_time()
        try:
            return real(*args, **kwargs)
        finally:
            writes.append((time.perf_counter() - started, time.process_time() - cpu))

    rerun_export.recording_bytes = timed
    ends: list[tuple[float, float]] = []
    try:
        ablation = Ablation(scenario, plugins, RunFolder(folder), recordings=recordings)
        try:
            started = (time.perf_counter(), time.process_time())
            ablation.run(lambda result: ends.append((time.perf_counter(), time.process_time())))
            total = time.perf_counter() - started[0]
        finally:
            ablation.close()
    finally:
        rerun_export.recording_bytes = real
    return total, [(b[0] - a[0], b[1] - a[1]) for a, b in zip([started, *ends], ends)]


def view(run: Path, site: Path, serial: bool = False) -> tuple[float, float]:
    """Seconds of ``safeembodai view RUN --out SITE`` in a fresh process: wall, and CPU (its own and its
    helpers'); ``serial``: the same build in one process (``build_site(parallel=False)``)."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    started = time.perf_counter()
    command = ([sys.executable, "-c", "import sys; from safeembodai_core.view import build_site; "
                "build_site(sys.argv[1], sys.argv[2], parallel=False)", str(run), str(site)] if serial else
               [sys.executable, "-m", "safeembodai_core", "view", str(run), "--out", str(site)])
    subprocess.run(command, check=True, capture_output=True)
    wall = time.perf_counter() - started
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def _size(folder: Path) -> int:
    """The bytes of the files under ``folder``."""
    return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=10, help="trials per cell (mo.yaml has 4 cells)")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()

    from safeembodai_core.plugin.manager import load_plugins
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
        writes_all: list[tuple[float, float]] = []
        trials_all: list[tuple[float, float]] = []
        for round_ in range(args.repeat):
            total, _ = ablate(scenario, plugins, root / f"plain{round_}", False, [])
            plain.append(total)
            writes: list[tuple[float, float]] = []
            total, trials = ablate(scenario, plugins, root / f"rrd{round_}", True, writes)
            recorded.append(total)
            assert len(writes) == len(trials), (len(writes), len(trials))
            writes_all += writes
            trials_all += trials
            n = len(trials)
            print(f"round {round_ + 1}: {n} trials; {plain[-1] / n:.3f} s per trial without recordings, "
                  f"{recorded[-1] / n:.3f} s with (x{recorded[-1] / plain[-1]:.2f}); load {os.getloadavg()[0]:.1f}")
        for kind, i in (("wall", 0), ("CPU", 1)):
            shares = [w[i] / t[i] for w, t in zip(writes_all, trials_all)]
            print(f"{kind}: writing a trial's .rrd median {statistics.median(w[i] for w in writes_all) * 1000:.0f} ms "
                  f"of a trial's {statistics.median(t[i] for t in trials_all) * 1000:.0f} ms; per trial, its share "
                  f"median {statistics.median(shares):.1%}, mean {statistics.mean(shares):.1%}, max {max(shares):.1%}; "
                  f"all writing / all trials {sum(w[i] for w in writes_all) / sum(t[i] for t in trials_all):.1%} "
                  "(bar: <= 15%)")
        print(f"whole run with recordings / without: x{statistics.median(recorded) / statistics.median(plain):.3f}")
        run = root / "rrd0"
        recordings = sorted((run / "recordings").glob("*.rrd"))
        size = sum(p.stat().st_size for p in recordings) / max(1, len(recordings)) / 1024
        print(f"{len(recordings)} recordings, {size:.0f} KiB each on average")
        cold, cold_cpu = view(run, root / "site")
        again, _ = view(run, root / "site")
        print(f"safeembodai view of the {len(recordings)}-trial run: cold {cold:.1f} s wall, {cold_cpu:.1f} s CPU "
              f"(bar: <= 20 s on 2 cores), unchanged rebuild {again:.1f} s; load {os.getloadavg()[0]:.1f}")
        print(f"the site: {_size(root / 'site') / 2**20:.1f} MiB; view cold / that run's own time (round 1, with "
              f"recordings, {recorded[0]:.1f} s wall): x{cold / recorded[0]:.2f} (issue 50: below x1)")
        serial, serial_cpu = view(run, root / "site-serial", serial=True)
        print(f"the same build in one process: cold {serial:.1f} s wall, {serial_cpu:.1f} s CPU; "
              f"load {os.getloadavg()[0]:.1f}")
        plain_view, plain_cpu = view(root / "plain0", root / "site-plain")
        print(f"the same run without recordings: cold {plain_view:.1f} s wall, {plain_cpu:.1f} s CPU; "
              f"load {os.getloadavg()[0]:.1f}")

if __name__ == "__main__":
    main()
