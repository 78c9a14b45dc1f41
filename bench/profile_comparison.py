"""How the comparison with the paper's figures moves between profiles (issue 22).

    python bench/profile_comparison.py RUN [RUN ...]

Reads each run folder's ``metrics.json`` and ``scenario.json`` (no re-computation) and prints, per
run: its profile, and for each metric the paper reports, how many of the run's cells have the
paper's value inside our 95% interval; then MOER per cell, side by side for every run, with the
paper's value. A cell is compared only where the paper has one: the release profile's conditions
(``attack_omi``, ``attack_ghi``) are not the paper's ``attack`` (which pools its prompts), so they
are not compared. Numbers only; the pilot of the shipped scenarios is the offline mock, so
agreement shows how its inputs were calibrated, not how an LLM behaves.
"""

from __future__ import annotations

import json
import sys
from collections import defaultdict
from pathlib import Path


def _run(folder: Path) -> tuple[str, list[dict]]:
    for name in ("scenario.json", "metrics.json"):
        if not (folder / name).is_file():
            sys.exit(f"{folder}: no {name} (not a run folder, or its run has not finished its report)")
    scenario = json.loads((folder / "scenario.json").read_text(encoding="utf-8"))["scenario"]
    profile = scenario.get("profile")
    name = profile.get("name") if isinstance(profile, dict) else profile
    cells = json.loads((folder / "metrics.json").read_text(encoding="utf-8"))["cells"]
    return f"{scenario['name']} ({name or 'no profile'}; N = {cells[0]['trials']} per cell)", cells


def main(folders: list[Path]) -> None:
    from safeembodai_core.report.paper import compared, paper_value

    runs = [_run(folder) for folder in folders]
    moer: dict[tuple, dict[str, str]] = defaultdict(dict)
    for label, cells in runs:
        inside: dict[str, list[bool]] = defaultdict(list)
        for cell in cells:
            key = (cell["environment"], cell["arm"], cell["condition"])
            for ours, theirs in compared().items():
                paper = paper_value(theirs, *key)
                low, high = cell.get(f"{ours}_low"), cell.get(f"{ours}_high")
                if paper is None or low is None or high is None:
                    continue
                inside[theirs].append(low - 1e-9 <= paper <= high + 1e-9)
            paper = paper_value("moer", *key)
            if cell.get("moer") is not None:
                moer[key]["paper"] = "--" if paper is None else f"{paper:.2f}"
                moer[key][label] = f"{cell['moer']:.2f} [{cell['moer_low']:.2f}, {cell['moer_high']:.2f}]"
        print(f"{label}: the paper's value inside our 95% interval")
        for metric, flags in inside.items():
            print(f"  {metric:12s} {sum(flags):3d} of {len(flags):3d} cells")
    labels = [label for label, _ in runs]
    print("\nMOER per cell (ours [95% interval]; the paper's read off its figures)")
    print("| env | arm | condition | paper | " + " | ".join(labels) + " |")
    print("|---|---|---|---|" + "---|" * len(labels))
    for key in sorted(moer):
        row = moer[key]
        print(f"| {' | '.join(key)} | {row.get('paper', '--')} | "
              + " | ".join(row.get(label, "--") for label in labels) + " |")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main([Path(arg) for arg in sys.argv[1:]])
