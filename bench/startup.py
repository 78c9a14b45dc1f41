"""Start-up time of the command line: `safeembodai --help` and `import safeembodai_core`.

Prints the median wall time and the median CPU time (user + system, of the child process) of N
fresh interpreter runs for each, and the ratio to a bare interpreter start (the part no Python CLI
can avoid). Target (issue 25): `safeembodai --help` at most 0.3 s of CPU. CPU time is what the
target counts: wall time on a shared 2-core machine moves with the other load.

    python bench/startup.py [--runs 15]
"""

from __future__ import annotations

import argparse
import resource
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


def measure(command: list[str], runs: int) -> tuple[float, float]:
    """Median wall seconds and median CPU seconds (user + system of the child) of ``runs`` runs."""
    walls, cpus = [], []
    for _ in range(runs):
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        started = time.perf_counter()
        subprocess.run(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=True)
        walls.append(time.perf_counter() - started)
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
        cpus.append(after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime)
    return statistics.median(walls), statistics.median(cpus)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=15)
    args = parser.parse_args()
    results = {name: measure(command, args.runs) for name, command in CASES.items()}
    bare_cpu = results["bare interpreter"][1]
    sys.stdout.write(f"{'case':28} {'wall s':>7} {'CPU s':>7} {'CPU x bare':>11}\n")
    for name, (wall, cpu) in results.items():
        sys.stdout.write(f"{name:28} {wall:7.3f} {cpu:7.3f} {cpu / bare_cpu:11.1f}\n")
    cpu = results["safeembodai --help"][1]
    verdict = "meets" if cpu <= 0.3 else "MISSES"
    sys.stdout.write(f"safeembodai --help {cpu:.3f} s CPU {verdict} the 0.3 s target\n")


if __name__ == "__main__":
    main()
