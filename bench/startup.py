"""Start-up time of the command line: `safeembodai --help` and `import safeembodai_core`.

Prints the median of N fresh interpreter runs for each, and the ratio to a bare interpreter start
(the part no Python CLI can avoid). Target: `safeembodai --help` under 0.5 s.

    python bench/startup.py [--runs 15]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

CASES = {
    "bare interpreter": [sys.executable, "-c", "pass"],
    "import safeembodai_core": [sys.executable, "-c", "import safeembodai_core"],
    "safeembodai --help": [sys.executable, "-m", "safeembodai_core", "--help"],
    "safeembodai plugins": [sys.executable, "-m", "safeembodai_core", "plugins", "--json"],
}


def measure(command: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        times.append(time.perf_counter() - started)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15)
    args = parser.parse_args()
    bare = measure(CASES["bare interpreter"], args.runs)
    sys.stdout.write(f"{'case':28} {'median s':>9} {'x bare':>7}\n")
    for name, command in CASES.items():
        seconds = bare if name == "bare interpreter" else measure(command, args.runs)
        sys.stdout.write(f"{name:28} {seconds:9.3f} {seconds / bare:7.1f}\n")
    help_time = measure(CASES["safeembodai --help"], args.runs)
    verdict = "meets" if help_time < 0.5 else "MISSES"
    sys.stdout.write(f"safeembodai --help {help_time:.3f} s {verdict} the 0.5 s target\n")


if __name__ == "__main__":
    main()
