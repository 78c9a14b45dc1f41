"""What the site says of a run folder: its summary (the index row) and its trials (the run page).

Read-only: the results store is opened read-only, a run's lock is probed without being taken
(:func:`running`), and nothing is written into the run folder.
"""

from __future__ import annotations

import os
from collections import Counter
from dataclasses import dataclass, field
from datetime import datetime, timezone
from pathlib import Path
from stat import S_ISLNK, S_ISREG
from typing import Any

from ..runs.folder import COORDINATOR_LOCK, LEDGER_FILE, SCENARIO_FILE, RunFolder
from ..errors import SafeEmbodAIError
from ..runs.files import FIGURES_DIR, RECORDINGS_DIR, UnreadableFile, folder_names
from .report_tables import report_tables


def find_runs(source: Path) -> list[Path]:
    """``source`` itself when it is a run folder (holds ``scenario.json``), else the run folders in it and
    one level further down (``ablate --out runs/X`` puts its run in ``runs/X/<scenario>-<time>``), by path.
    A folder that holds none is an error naming it (a ``safeembodai run`` folder is one trial, not a run)."""
    if (source / SCENARIO_FILE).is_file():
        return [source]
    if not source.is_dir():
        raise SafeEmbodAIError(f"{source} is neither a run folder nor a folder of runs")
    found = []
    for child in sorted(p for p in source.iterdir() if p.is_dir() and not p.is_symlink()):
        if (child / SCENARIO_FILE).is_file():
            found.append(child)
        else:
            found += sorted(p for p in child.iterdir() if p.is_dir() and not p.is_symlink()
                            and (p / SCENARIO_FILE).is_file())
    if not found:
        raise SafeEmbodAIError(f"{source} holds no run folder (a run folder, which 'safeembodai ablate' writes, holds "
                               f"{SCENARIO_FILE}; a 'safeembodai run' folder holds one trial's trial.json)")
    return found


#: Files by which a folder that is no run folder is known as another output of the framework, and why
#: ``view`` leaves it out (listed on the index and in the line the command prints).
NOT_A_RUN = (("trial.json", "a 'safeembodai run' folder: one trial, not a run; 'safeembodai show' reads it"),
             (LEDGER_FILE, f"a run's ledger without its {SCENARIO_FILE}: not readable as a run"))


def skipped_folders(source: Path) -> list[tuple[Path, str]]:
    """The folders :func:`find_runs` leaves out that are the framework's own outputs, each with why
    (:data:`NOT_A_RUN`), at the same depths it looks at."""
    if (source / SCENARIO_FILE).is_file() or not source.is_dir():
        return []
    candidates = []
    for child in sorted(p for p in source.iterdir() if p.is_dir() and not p.is_symlink()):
        candidates.append(child)
        if not (child / SCENARIO_FILE).is_file():
            candidates += sorted(p for p in child.iterdir() if p.is_dir() and not p.is_symlink())
    skipped = []
    for folder in candidates:
        if (folder / SCENARIO_FILE).is_file():
            continue
        why = next((reason for name, reason in NOT_A_RUN if (folder / name).is_file()), None)
        if why is not None:
            skipped.append((folder, why))
    return skipped


def running(folder: Path) -> bool:
    """Whether an ``ablate`` holds the run now: its coordinator lock file exists and is locked.
    Probed with a shared, non-blocking lock on a read-only, non-blocking open of a regular file (a FIFO
    or a symlink there is no lock): never created, never kept."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX: no locks to probe
        return False
    try:
        fd = os.open(folder / COORDINATOR_LOCK, os.O_RDONLY | os.O_NONBLOCK | os.O_NOFOLLOW)
    except OSError:
        return False
    try:
        if not S_ISREG(os.fstat(fd).st_mode):
            return False
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    else:
        fcntl.flock(fd, fcntl.LOCK_UN)
        return False
    finally:
        os.close(fd)


def signature(folder: Path) -> str:
    """Changes whenever the run's results may have: the size and time of every file directly in
    the run folder -- scenario, ledger, lock, report, and whatever files the state store keeps
    there (its name for them is the store's business, not the view's) -- and in its ``recordings/``
    (Rerun recordings exported there after the run); a symlink there by its name only (it is read as
    none: :func:`~safeembodai_core.runs.files.open_inside`), so one coming or going renders the run anew."""
    parts = []
    try:
        paths = sorted(folder.iterdir())
        recordings = folder / RECORDINGS_DIR
        if recordings.is_dir() and not recordings.is_symlink():
            paths += sorted(recordings.iterdir())
    except OSError:
        return "-"
    for path in paths:
        try:
            stat = path.lstat()
        except OSError:
            continue
        if S_ISLNK(stat.st_mode):
            parts.append(f"{path.relative_to(folder)}:symlink")
        elif S_ISREG(stat.st_mode):
            parts.append(f"{path.relative_to(folder)}:{stat.st_size}:{stat.st_mtime_ns}")
    return "|".join(parts)


@dataclass
class TrialRow:
    trial_id: str
    page: str
    environment: str
    arm: str
    condition: str
    index: int
    outcome: str
    steps: int
    refusals: int
    collisions_self: int
    collisions_struck: int
    detail: str
    struck_standing: int | None = None  # of the struck: while the robot stood (None: not recorded)


@dataclass
class CellRow:
    environment: str
    arm: str
    condition: str
    trials: int
    moer: str
    completed: str


@dataclass
class RunSummary:
    name: str
    path: Path
    when: str
    scenario: str
    backend: str
    model: str
    pilot: str
    seed: int
    trials_per_cell: int
    total: int
    finished: int
    status: str  # running, finished, interrupted
    simulated: str | None
    cells: list[CellRow] = field(default_factory=list)
    trials: list[TrialRow] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    tables: list[Any] = field(default_factory=list)  # report.md's tables (report_tables.Table)
    error: str | None = None
    page: str = ""  # the run page, relative to the site (none for an unreadable run)
    nodes: list[tuple[str, int]] = field(default_factory=list)  # Ray nodes and their trials (none: this machine)
    left_out: list[str] = field(default_factory=list)  # the run's files there but refused, and why (its page)


def trial_page(trial_id: str) -> str:
    """The file name of a trial's page (also its images' folder): one safe file name."""
    from .files import safe_name

    from ..runs.files import trial_file_name

    return safe_name(trial_file_name(trial_id))


def summarise(folder: Path, plugins: Any) -> tuple[RunSummary, Any, Any]:
    """The run's summary with its cells and trials, the runner (to replay trials) and the results."""
    from ..report.cells import scenario_cells
    from ..report.run_info import run_info
    from ..runs.runner import ScenarioRunner

    scenario = RunFolder(folder).scenario()
    runner = ScenarioRunner(scenario, plugins, run_dir=folder)
    try:
        results = runner.in_trial_order(runner.state.results())
        info = run_info(scenario, folder, plugins, results)
        total = len(runner.specs())
        state = "running" if running(folder) else "finished" if len(results) >= total else "interrupted"
        stamp = datetime.fromtimestamp((folder / SCENARIO_FILE).stat().st_mtime, tz=timezone.utc)
        summary = RunSummary(
            name=folder.name, path=folder, when=stamp.strftime("%Y-%m-%d %H:%M UTC"), scenario=scenario.name,
            backend=info.backend, model=info.model, pilot=info.pilot, seed=info.seed,
            trials_per_cell=info.trials_per_cell, total=total, finished=len(results), status=state,
            simulated=info.simulated)
        for cell in scenario_cells(scenario, results) if results else []:
            m = cell.metrics
            summary.cells.append(CellRow(m.environment, m.arm, m.condition, m.trials, m.moer.fmt(), m.completion.fmt()))
        for r in results:
            s = r.spec
            summary.trials.append(TrialRow(s.trial_id, trial_page(s.trial_id), s.environment, s.arm, s.condition,
                                           s.index, r.outcome.value, r.steps, r.interventions, r.collisions_self,
                                           r.collisions_struck, r.detail, r.collisions_struck_standing))
        if any(r.node for r in results):
            counts = Counter(r.node or "this machine" for r in results)
            summary.nodes = sorted(counts.items())
        summary.tables = report_tables(folder / "report.md")
        summary.figures = _figures(folder, summary.left_out)
    except BaseException:  # the caller gets no runner to close: close it here
        runner.close()
        raise
    return summary, runner, results


def _figures(folder: Path, left_out: list[str]) -> list[str]:
    """The PNG names in the run's ``figures/``, reached with no symlink (a ``figures/`` that is one is
    left out, said in ``left_out``)."""
    try:
        names = folder_names(folder, folder / FIGURES_DIR)
    except FileNotFoundError:
        return []
    except (OSError, SafeEmbodAIError) as error:
        why = error.reason if isinstance(error, UnreadableFile) else str(error)
        left_out.append(f"{FIGURES_DIR}/: {why}")
        return []
    return [name for name in names if name.endswith(".png")]


def broken(folder: Path, error: Exception) -> RunSummary:
    """The index row of a run folder that cannot be read (its error shown, the rest left empty)."""
    try:
        name = RunFolder(folder).recorded_scenario()["scenario"].get("name", "?")
    except SafeEmbodAIError:  # the bounded reader's refusal (a FIFO, a symlink, not JSON): the row shows the error
        name = "?"
    return RunSummary(name=folder.name, path=folder, when="", scenario=str(name), backend="", model="", pilot="",
                      seed=0, trials_per_cell=0, total=0, finished=0, status="unreadable", simulated=None,
                      error=str(error))
