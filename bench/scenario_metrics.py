"""Every shipped scenario's ``metrics.csv`` at a few trials per cell, and two such sets compared: the check
that a change meant to keep behaviour (a move, a faster step) kept it.

    python bench/scenario_metrics.py run OUT [--trials 2]     # this tree's code, one scenario after another
    python bench/scenario_metrics.py compare BEFORE AFTER       # every cell and column; exit 1 on a difference

Run ``run`` on a checkout of the commit before the change and on the change, then ``compare``. The
scenarios run as shipped (their seeds, the mock pilot) with ``trials`` set; ``mcp.yaml`` is
``agent-ablate``'s and is left out. Prints one line per scenario: rows, and differences (cell and column).
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
LEFT_OUT = {"mcp"}  # agent-ablate's scenario, not ablate's


def run(out: Path, trials: int) -> int:
    out.mkdir(parents=True, exist_ok=True)
    failed = 0
    for scenario in sorted((REPO / "scenarios").glob("*.yaml")):
        if scenario.stem in LEFT_OUT:
            continue
        folder = out / scenario.stem
        done = subprocess.run([sys.executable, "-m", "safeembodai_core", "ablate", str(scenario), "--set",
                               f"trials={trials}", "--out", str(folder)], cwd=REPO, capture_output=True, text=True)
        runs = sorted(folder.glob("*/metrics.csv"))
        if done.returncode or not runs:
            failed += 1
            print(f"{scenario.stem}: failed (exit {done.returncode}): {done.stderr.strip()[-300:]}")
            continue
        (out / f"{scenario.stem}.metrics.csv").write_bytes(runs[-1].read_bytes())
        print(f"{scenario.stem}: {out / (scenario.stem + '.metrics.csv')}")
    return 1 if failed else 0


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="", encoding="utf-8") as handle:
        return list(csv.DictReader(handle))


def compare(before: Path, after: Path) -> int:
    different = 0
    for old in sorted(before.glob("*.metrics.csv")):
        new = after / old.name
        if not new.exists():
            print(f"{old.name}: missing in {after}")
            different += 1
            continue
        a, b = _rows(old), _rows(new)
        cells = [f"{r.get('environment')}/{r.get('arm')}/{r.get('condition')} {k}: {r.get(k)!r} -> {s.get(k)!r}"
                 for r, s in zip(a, b) for k in sorted(set(r) | set(s)) if r.get(k) != s.get(k)]
        if len(a) != len(b):
            cells.insert(0, f"{len(a)} rows -> {len(b)}")
        different += bool(cells)
        print(f"{old.stem.removesuffix('.metrics')}: {len(a)} rows, {len(cells)} differences"
              + "".join(f"\n  {c}" for c in cells[:10]))
    return 1 if different else 0


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    commands = parser.add_subparsers(dest="command", required=True)
    running = commands.add_parser("run")
    running.add_argument("out", type=Path)
    running.add_argument("--trials", type=int, default=2)
    comparing = commands.add_parser("compare")
    comparing.add_argument("before", type=Path)
    comparing.add_argument("after", type=Path)
    args = parser.parse_args()
    if args.command == "run":
        return run(args.out, args.trials)
    return compare(args.before, args.after)


if __name__ == "__main__":
    sys.exit(main())
