"""``safeembodai view``'s site: an index of run folders, a page per run and a page per trial.

Static and self-contained: HTML, one stylesheet, one script, and the images copied in -- nothing
fetched from elsewhere when it is read. Incremental: a run whose folder has not changed since the
last build (:func:`~safeembodai_core.view.runs.signature`, kept in ``manifest.json``) is not
rendered again, and within a run only new or changed trials' pages are.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

from ..logs import get_logger
from .html import STATIC, render, write_atomic
from .runs import CellRow, RunSummary, broken, find_runs, signature, summarise, trial_page
from .trial_steps import replayed_prompts, step_views

log = get_logger(__name__)
MANIFEST = "manifest.json"


def _manifest(out: Path) -> dict[str, Any]:
    try:
        value = json.loads((out / MANIFEST).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return {}
    return value if isinstance(value, dict) and value.get("version") == 1 else {}


def build_site(source: str | Path, out: str | Path, plugins: Any = None, refresh: int = 0) -> dict[str, int]:
    """Render the site of ``source`` (a run folder, or a folder of them) into ``out``; return how
    many runs and trial pages were (re)rendered. ``refresh``: seconds after which the index and
    the pages of running runs ask the browser to reload (0: never)."""
    from ..plugins import load_plugins

    source, out = Path(source), Path(out)
    plugins = plugins or load_plugins()
    out.mkdir(parents=True, exist_ok=True)
    for asset in ("view.css", "view.js", "favicon.png"):
        write_atomic(out / asset, (STATIC / asset).read_bytes())
    manifest = _manifest(out)
    runs: dict[str, Any] = manifest.get("runs", {})
    summaries: list[RunSummary] = []
    counts = {"runs": 0, "trials": 0}
    for folder in find_runs(source):
        stamp = signature(folder)
        known = runs.get(folder.name, {})
        if known.get("signature") == stamp and (out / "runs" / folder.name / "index.html").is_file():
            cached = known["summary"]
            summaries.append(RunSummary(**{**cached, "path": folder, "cells": [CellRow(**c) for c in cached["cells"]]}))
            continue
        try:
            summary, trials = _render_run(folder, out / "runs" / folder.name, plugins, known.get("trials", {}),
                                          refresh)
        except Exception as error:  # one unreadable folder must not hide the others
            log.warning("view.run_unreadable", run=str(folder), error=str(error))
            summary, trials = broken(folder, error), {}
        counts["runs"] += 1
        counts["trials"] += sum(1 for t in trials.values() if t.get("rendered"))
        runs[folder.name] = {"signature": stamp, "trials": {k: {"key": v["key"]} for k, v in trials.items()},
                             "summary": _plain(summary)}
        summaries.append(summary)
    write_atomic(out / "index.html", render("index.html.j2", runs=summaries, refresh=refresh))
    write_atomic(out / MANIFEST, json.dumps({"version": 1, "runs": runs}, indent=1))
    return counts


def _plain(summary: RunSummary) -> dict[str, Any]:
    """What the index needs of a run, kept in the manifest for runs not rendered again."""
    fields = dict(vars(summary))
    fields.pop("path")
    fields["cells"] = [vars(c) for c in summary.cells]
    fields["trials"], fields["tables"] = [], []
    return fields


def _render_run(folder: Path, target: Path, plugins: Any, known: dict[str, Any],
                refresh: int) -> tuple[RunSummary, dict]:
    summary, runner, results = summarise(folder, plugins)
    try:
        for name in summary.figures:
            target.joinpath("figures").mkdir(parents=True, exist_ok=True)
            shutil.copyfile(folder / "figures" / name, target / "figures" / name)
        trials: dict[str, dict[str, Any]] = {}
        for result in results:
            spec = result.spec
            key = result.model_dump_json()
            page = target / "trials" / f"{trial_page(spec.trial_id)}.html"
            rendered = not (known.get(spec.trial_id, {}).get("key") == key and page.is_file())
            if rendered:
                _render_trial(folder, target, runner, summary, result)
            trials[spec.trial_id] = {"key": key, "rendered": rendered}
        write_atomic(target / "index.html", render("run.html.j2", run=summary,
                                                   refresh=refresh if summary.status == "running" else 0))
    finally:
        runner.close()
    return summary, trials


def _render_trial(folder: Path, target: Path, runner: Any, summary: RunSummary, result: Any) -> None:
    spec = result.spec
    name = trial_page(spec.trial_id)
    records = runner.state.steps(spec.trial_id)
    prompts, missing = replayed_prompts(runner, spec, records) if records else ({}, "no step was recorded")
    steps = step_views(records, prompts, target / "img" / name, f"../img/{name}")
    picture = folder / "trajectories" / f"{name}.png"
    trajectory = None
    if picture.is_file():
        (target / "img").mkdir(parents=True, exist_ok=True)
        shutil.copyfile(picture, target / "img" / f"{name}.png")
        trajectory = f"../img/{name}.png"
    write_atomic(target / "trials" / f"{name}.html",
                 render("trial.html.j2", run=summary, result=result, steps=steps, trajectory=trajectory,
                        missing=missing, refresh=0))
