"""``safeembodai view``'s site: an index of run folders, a page per run and a page per trial.

Static and self-contained: HTML, one stylesheet, one script, and the images copied in -- nothing
fetched from elsewhere when it is read. Incremental: a run whose folder has not changed since the
last build (:func:`~safeembodai_core.view.runs.signature`, kept in ``manifest.json``) is not
rendered again, and within a run only new or changed trials' pages are. A run with many trial pages
to render shares them with helper processes, one per further core (:data:`PARALLEL_FROM`): a page
replays its trial, most of a cold build's time.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..logs import get_logger
from ..runs.runner import trajectory_file
from ..runs.files import FIGURES_DIR, MAX_RECORDING_BYTES, RECORDINGS_DIR, RRD_MAGIC
from ..runs.trial_files import recording_file
from .files import MANIFEST, Site, read_run_file, safe_name
from .html import STATIC, render
from .rerun_viewer import VIEWER_PREFIX
from .runs import (
    CellRow, RunSummary, broken, find_runs, running, signature, skipped_folders, summarise, trial_page,
)
from .trial_steps import replayed_prompts, step_views

log = get_logger(__name__)
#: Bumped whenever what the manifest keeps of a run changes: an older manifest is rendered anew.
MANIFEST_VERSION = 2


#: A run with at least this many trial pages to render shares them with helper processes (spawned:
#: each loads the plugins and opens the run again, about 2 s), one per core beyond the first, at most
#: :data:`MAX_HELPERS`, and only when the site is built with the installed plugins (``parallel``).
PARALLEL_FROM = 8
MAX_HELPERS = 3


def helpers_for(pages: int) -> int:
    """How many helper processes render ``pages`` trial pages beside this one."""
    if pages < PARALLEL_FROM:
        return 0
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        cores = os.cpu_count() or 1
    return max(0, min(cores - 1, MAX_HELPERS, pages // (PARALLEL_FROM // 2) - 1))


def _recording_stamp(folder: Path, trial_id: str) -> str:
    """The size and time of the trial's recording (``RUN/recordings/``), so an export after the page
    was rendered renders it anew with its link; "" without one."""
    try:
        stat = recording_file(folder, trial_id).lstat()
    except OSError:
        return ""
    return f"|rrd:{stat.st_size}:{stat.st_mtime_ns}"


def _manifest(site: Site) -> dict[str, Any]:
    try:
        value = json.loads(site.read(MANIFEST) or "")
    except ValueError:
        return {}
    return value if isinstance(value, dict) and value.get("version") == MANIFEST_VERSION else {}


def _cached(known: dict[str, Any], folder: Path) -> RunSummary | None:
    """The index row the manifest kept of a run, or None when it does not fit (then it is rendered anew)."""
    try:
        cached = dict(known["summary"])
        cached["cells"] = [CellRow(**c) for c in cached["cells"]]
        return RunSummary(**{**cached, "path": folder})
    except (KeyError, TypeError, ValueError):
        return None


def build_site(source: str | Path, out: str | Path, plugins: Any = None, refresh: int = 0,
               viewer: bool = False, parallel: bool = False) -> dict[str, Any]:
    """Render the site of ``source`` (a run folder, or a folder of them) into ``out``; return how many
    runs were found (``found``) and how many runs and trial pages were (re)rendered. ``refresh``:
    seconds after which the index and the pages of running runs ask the browser to reload (0: never).
    ``viewer``: the site is served with Rerun's web viewer beside it (``view --serve``,
    :mod:`.rerun_viewer`): a trial page with a recording links to it there too. ``parallel``: helper
    processes may render trial pages (:func:`helpers_for`): spawned, they load the installed plugins
    and import the caller's main module again (``safeembodai view`` builds so; a script that does
    must be ``if __name__ == "__main__"``-guarded and build with the installed plugins)."""
    from ..plugin.manager import load_plugins

    source = Path(source)
    folders = find_runs(source)  # none: an error, before any file of the site is written
    site = Site(Path(out))
    plugins = plugins or load_plugins()
    for asset in ("view.css", "view.js", "favicon.png"):
        site.write(asset, (STATIC / asset).read_bytes())
    runs: dict[str, Any] = _manifest(site).get("runs", {})
    summaries: list[RunSummary] = []
    skipped = [(folder.relative_to(source).as_posix(), why) for folder, why in skipped_folders(source)]
    counts: dict[str, Any] = {"found": len(folders), "runs": 0, "trials": 0, "skipped": skipped}
    for folder in folders:
        stamp = f"{signature(folder)}|running:{running(folder)}"  # a run that stopped is rendered anew
        if viewer and (folder / RECORDINGS_DIR).is_dir():  # its recordings' pages get the viewer's link
            stamp += "|viewer"
        key = folder.name if folder == source else folder.relative_to(source).as_posix()  # runs/X/mo-...: X/mo-...
        known = runs.get(key, {})
        name = safe_name(key.replace("/", "-"))
        cached = _cached(known, folder) if known.get("signature") == stamp else None
        if cached is not None and (site.out / "runs" / name / "index.html").is_file():
            summaries.append(cached)
            continue
        try:
            summary, trials = _render_run(folder, site, f"runs/{name}", plugins, known.get("trials", {}), refresh,
                                          viewer, parallel)
        except Exception as error:  # one unreadable folder must not hide the others
            log.warning("view.run_unreadable", run=str(folder), error=str(error))
            summary, trials = broken(folder, error), {}
        summary.page = f"runs/{name}/index.html"
        counts["runs"] += 1
        counts["trials"] += sum(1 for t in trials.values() if t.get("rendered"))
        runs[key] = {"signature": stamp, "trials": {k: {"key": v["key"]} for k, v in trials.items()},
                             "summary": _plain(summary)}
        summaries.append(summary)
    site.write("index.html", render("index.html.j2", runs=summaries, skipped=skipped, refresh=refresh))
    site.write(MANIFEST, json.dumps({"version": MANIFEST_VERSION, "runs": runs}, indent=1))
    return counts


def _plain(summary: RunSummary) -> dict[str, Any]:
    """What the index needs of a run, kept in the manifest for runs not rendered again."""
    fields = dict(vars(summary))
    fields.pop("path")
    fields["cells"] = [vars(c) for c in summary.cells]
    fields["trials"], fields["tables"] = [], []
    return fields


def _render_run(folder: Path, site: Site, base: str, plugins: Any, known: dict[str, Any],
                refresh: int, viewer: bool = False, parallel: bool = False) -> tuple[RunSummary, dict]:
    summary, runner, results = summarise(folder, plugins)
    try:
        shown = []
        for name in summary.figures:  # a regular PNG, no symlink anywhere below the run folder
            picture = read_run_file(folder / FIGURES_DIR / name, png=True, folder=folder, left_out=summary.left_out)
            if picture is not None:
                site.write(f"{base}/figures/{safe_name(name)}", picture)
                shown.append(safe_name(name))
        summary.figures = shown
        trials: dict[str, dict[str, Any]] = {}
        todo = []
        for result in results:
            spec = result.spec
            recorded = _recording_stamp(folder, spec.trial_id)
            key = result.model_dump_json() + recorded + ("|viewer" if viewer and recorded else "")
            page = site.out / base / "trials" / f"{trial_page(spec.trial_id)}.html"
            rendered = not (known.get(spec.trial_id, {}).get("key") == key and page.is_file())
            if rendered:
                todo.append(result)
            trials[spec.trial_id] = {"key": key, "rendered": rendered}
        _render_trials(folder, site, base, runner, summary, todo, viewer, helpers_for(len(todo)) if parallel else 0)
        site.write(f"{base}/index.html", render("run.html.j2", run=summary,
                                               refresh=refresh if summary.status == "running" else 0))
    finally:
        runner.close()
    return summary, trials


def _render_trials(folder: Path, site: Site, base: str, runner: Any, summary: RunSummary, todo: list[Any],
                   viewer: bool, helpers: int) -> None:
    """Render the trial pages of ``todo``: here, and shared with ``helpers`` spawned processes (each
    its own runner of the run: pybullet and threads are never forked); an error in one is raised here."""
    if not helpers:
        for result in todo:
            _render_trial(folder, site, base, runner, summary, result, viewer)
        return
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    from concurrent.futures.process import BrokenProcessPool

    shares = [todo[i::helpers + 1] for i in range(helpers + 1)]  # interleaved: cells alike in cost
    with ProcessPoolExecutor(helpers, mp_context=multiprocessing.get_context("spawn")) as pool:
        futures = [pool.submit(_render_share, str(folder), str(site.out), base, summary, share, viewer)
                   for share in shares[1:]]
        for result in shares[0]:
            _render_trial(folder, site, base, runner, summary, result, viewer)
        for future, share in zip(futures, shares[1:]):
            try:
                future.result()
            except BrokenProcessPool as error:  # a helper could not start or died: its pages here
                log.warning("view.helper_failed", error=str(error))
                for result in share:
                    _render_trial(folder, site, base, runner, summary, result, viewer)


def _render_share(folder: str, out: str, base: str, summary: RunSummary, share: list[Any], viewer: bool) -> None:
    """A helper process's share of a run's trial pages: the installed plugins, a runner of its own."""
    from ..runs.folder import RunFolder
    from ..plugin.manager import load_plugins
    from ..runs.runner import ScenarioRunner

    run = Path(folder)
    runner = ScenarioRunner(RunFolder(run).scenario(), load_plugins(), run_dir=run)
    try:
        site = Site(Path(out), checked=True)
        for result in share:
            _render_trial(run, site, base, runner, summary, result, viewer)
    finally:
        runner.close()


def _render_trial(folder: Path, site: Site, base: str, runner: Any, summary: RunSummary, result: Any,
                  viewer: bool = False) -> None:
    spec = result.spec
    name = trial_page(spec.trial_id)
    records = runner.state.steps(spec.trial_id)
    prompts, scans, missing = replayed_prompts(runner, spec, records) if records else ({}, {}, "no step was recorded")
    robot = runner.environment(spec.environment).robot if scans else None
    steps = step_views(records, prompts, site, f"{base}/img/{name}", f"../img/{name}", scans,
                       robot.radius_mm if robot is not None else 170.0)
    left_out: list[str] = []  # the trial's files that are there but refused, and why: said on its page
    picture = read_run_file(trajectory_file(folder, spec.trial_id), png=True, folder=folder, left_out=left_out)
    trajectory = None
    if picture is not None:
        site.write(f"{base}/img/{name}.png", picture)
        trajectory = f"../img/{name}.png"
    recorded = read_run_file(recording_file(folder, spec.trial_id), MAX_RECORDING_BYTES, folder=folder,
                             left_out=left_out)
    recording = in_viewer = None
    if recorded is not None and not recorded.startswith(RRD_MAGIC):  # a Rerun recording, nothing else
        left_out.append(f"{recording_file(folder, spec.trial_id).relative_to(folder).as_posix()}: "
                        "not a Rerun recording")
    elif recorded is not None:
        site.write(f"{base}/recordings/{name}.rrd", recorded)
        recording = f"../recordings/{name}.rrd"
        if viewer:  # the site server's redirect to Rerun's web viewer opening it (.serve)
            in_viewer = f"../../..{VIEWER_PREFIX}{base}/recordings/{name}.rrd"
    site.write(f"{base}/trials/{name}.html",
               render("trial.html.j2", run=summary, result=result, steps=steps, trajectory=trajectory,
                      recording=recording, in_viewer=in_viewer, missing=missing, left_out=left_out, refresh=0))
