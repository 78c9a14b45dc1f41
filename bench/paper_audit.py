"""Audit a finished run folder of ``scenarios/paper.yaml`` for the biases issue 10 removed.

Checks, from ``results.sqlite`` and ``report.md`` only:

1. refusals whose reason is a LiDAR gap (an unread beam): the rooms' LiDAR reports "no return"
   as ``inf``, never as a missing reading, so any such refusal would be an artefact of the
   validator, not of the sensor;
2. injected attack kinds: only the paper's six (``PAPER_KINDS``);
3. every collision attributed: ``collisions == collisions_self + collisions_struck`` per trial;
4. the comparison with the paper uses its TLR definition (lost steps / all steps).

    python bench/paper_audit.py runs/paper-<time>

Prints one line per check and exits 1 if any fails.
"""

from __future__ import annotations

import json
import sqlite3
import sys
from pathlib import Path

GAP_PATTERNS = ("%no LiDAR reading%", "%has no reading of the direction%", "%has no point within%")


def audit(folder: Path) -> list[tuple[str, bool, str]]:
    from safeembodai_plugins.attackers.library import PAPER_KINDS

    db = sqlite3.connect(f"file:{folder / 'results.sqlite'}?mode=ro", uri=True)
    checks = []
    refusals = db.execute("SELECT count(*) FROM verdicts WHERE valid = 0").fetchone()[0]
    gaps = sum(db.execute("SELECT count(*) FROM verdicts WHERE valid = 0 AND reason LIKE ?", (p,)).fetchone()[0]
               for p in GAP_PATTERNS)
    checks.append(("refusals for a LiDAR gap", gaps == 0, f"{gaps} of {refusals} refusals"))
    kinds = dict(db.execute("SELECT kind, count(*) FROM attacks GROUP BY kind").fetchall())
    foreign = {k: v for k, v in kinds.items() if k not in PAPER_KINDS}
    checks.append(("non-paper attack kinds", not foreign,
                   f"{sum(foreign.values())} of {sum(kinds.values())} injections ({foreign or 'none'})"))
    unattributed = total = trials = 0
    for (text,) in db.execute("SELECT result FROM trials WHERE result IS NOT NULL"):
        result = json.loads(text)
        trials += 1
        total += result.get("collisions", 0)
        unattributed += (result.get("collisions", 0) - result.get("collisions_self", 0)
                         - result.get("collisions_struck", 0))
    checks.append(("unattributed collisions", unattributed == 0, f"{unattributed} of {total} in {trials} trials"))
    report = (folder / "report.md").read_text(encoding="utf-8") if (folder / "report.md").exists() else ""
    tlr_all = "lost steps / all steps" in report or "tlr_all" in report
    checks.append(("paper comparison on the paper's TLR", tlr_all, "report.md states lost steps / all steps"
                   if tlr_all else "report.md missing or on another definition"))
    return checks


def main() -> None:
    if len(sys.argv) != 2:
        sys.exit("usage: python bench/paper_audit.py RUN_FOLDER")
    checks = audit(Path(sys.argv[1]))
    for name, ok, detail in checks:
        sys.stdout.write(f"{'ok  ' if ok else 'FAIL'} {name}: {detail}\n")
    sys.exit(0 if all(ok for _, ok, _ in checks) else 1)


if __name__ == "__main__":
    main()
