"""How long the README's main job takes: ``safeembodai ablate scenarios/mo.yaml``, as a user runs it.

Each run is the command itself in a fresh process (start-up, plugins, the trials, the report and
figures), into a scratch folder, with no response cache. Runs alternate between an idle machine and
a loaded one (one busy-looping process per core, as when a test suite or a build runs beside it).
Printed: each run's seconds, the median per setting, and loaded / idle as a ratio.

    python bench/main_job.py [--repeat 3] [--set trials=2 ...]
"""

from __future__ import annotations

import argparse
import multiprocessing
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _burn(stop: multiprocessing.synchronize.Event) -> None:  # type: ignore[name-defined]
    while not stop.is_set():
        sum(i * i for i in range(10_000))


def run_once(overrides: list[str]) -> float:
    with tempfile.TemporaryDirectory() as scratch:
        command = [sys.executable, "-m", "safeembodai_core", "ablate", str(REPO / "scenarios" / "mo.yaml"),
                   "--out", str(Path(scratch) / "runs"), "--no-cache"]
        for item in overrides:
            command += ["--set", item]
        started = time.perf_counter()
        subprocess.run(command, check=True, capture_output=True, cwd=scratch)
        return time.perf_counter() - started


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args()
    cores = os.cpu_count() or 1
    times: dict[str, list[float]] = {"idle": [], "loaded": []}
    for _ in range(args.repeat):
        for setting in ("idle", "loaded"):
            stop = multiprocessing.Event()
            burners = [multiprocessing.Process(target=_burn, args=(stop,), daemon=True)
                       for _ in range(cores if setting == "loaded" else 0)]
            for burner in burners:
                burner.start()
            try:
                seconds = run_once(args.overrides)
            finally:
                stop.set()
                for burner in burners:
                    burner.join()
            times[setting].append(seconds)
            print(f"{setting:6} {seconds:6.1f} s")
    idle, loaded = statistics.median(times["idle"]), statistics.median(times["loaded"])
    print(f"main job (scenarios/mo.yaml{', ' + ', '.join(args.overrides) if args.overrides else ''}), "
          f"{cores} cores, {args.repeat} runs each: idle {idle:.1f} s, loaded ({cores} busy processes) "
          f"{loaded:.1f} s, loaded / idle {loaded / idle:.2f}")


if __name__ == "__main__":
    main()
