"""``safeembodai view``'s site, read as HTML: what it shows, that hostile text stays text, that it
fetches nothing from elsewhere, and that it renders only what changed."""

from __future__ import annotations

import json
import re
import shutil
from html.parser import HTMLParser
from pathlib import Path

import pytest

from safeembodai_core.cli import cli
from safeembodai_core.view import build_site
from safeembodai_core.view.html import CSP

pytestmark = pytest.mark.slow  # each builds whole sites of runs (module fixtures of 14-18 s)


class Page(HTMLParser):
    """The tags and attributes of a page, and its text."""

    def __init__(self, text: str) -> None:
        super().__init__(convert_charrefs=True)
        self.tags: list[tuple[str, dict[str, str | None]]] = []
        self.text: list[str] = []
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        self.tags.append((tag, dict(attrs)))

    def handle_data(self, data):
        self.text.append(data)

    def all(self, tag: str) -> list[dict[str, str | None]]:
        return [attrs for name, attrs in self.tags if name == tag]


@pytest.fixture(scope="module")
def site(runs_dir, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("site")
    build_site(runs_dir, out)
    return out


def pages(site: Path) -> list[Path]:
    return sorted(site.rglob("*.html"))


def test_every_page_loads_only_the_site_itself(site):
    """Each page carries the policy, and every link, image, script and stylesheet is a relative path
    inside the site that exists: nothing is fetched from elsewhere, no link leaves it."""
    assert len(pages(site)) == 1 + 2 + 40 + 4
    for path in pages(site):
        page = Page(path.read_text(encoding="utf-8"))
        assert {"http-equiv": "Content-Security-Policy", "content": CSP} in page.all("meta"), path
        for tag, attribute in (("a", "href"), ("img", "src"), ("script", "src"), ("link", "href")):
            for attrs in page.all(tag):
                target = attrs.get(attribute)
                assert target and not re.match(r"^[a-z][a-z0-9+.-]*:|^//", target, re.I), (path, target)
                assert (path.parent / target).resolve().is_file(), (path, target)
        scripts = page.all("script")
        assert scripts == [{"src": scripts[0]["src"], "defer": None}]  # ours alone, no inline script
        assert not any(name.startswith("on") for _, attrs in page.tags for name in attrs)  # no handlers


def test_hostile_answers_stay_text_and_invisible_characters_show(site):
    trial = site / "runs" / "hostile" / "trials" / "flatland__safeembodai__attack__0.html"
    html = trial.read_text(encoding="utf-8")
    page = Page(html)
    text = "".join(page.text)
    assert "<script>window.__pwned = 1</script>" in text  # shown as text ...
    assert "<script>window" not in html and "&lt;script&gt;window" in html  # ... because it was escaped
    assert "![tracker](http://evil.example/pixel.png)" in text and "javascript:" not in "".join(
        str(v) for _, attrs in page.tags for v in attrs.values())
    assert "\\u202egnp.exe\\u202c" in text and "zero\\u200bwidth" in text and "NUL\\x00" in text
    assert not re.search("[\u202e\u200b\x00\x1b]", html)
    # the refusal of the answer that did not parse, and the instruction, are there too
    assert "not read:" in text and "Find the can." in text


def test_the_index_lists_every_run_with_its_cells(site):
    page = Page((site / "index.html").read_text(encoding="utf-8"))
    rows = [attrs for attrs in page.all("tr") if "run" in (attrs.get("class") or "")]
    assert len(rows) == 2
    text = "".join(page.text)
    assert "mo-40" in text and "hostile" in text and "finished" in text
    assert "MO/safeembodai/attack: " in text and "simulated" in text
    assert text.count("40 / 40") == 1


def test_a_run_page_has_its_trials_metrics_figures_and_banner(site):
    page = Page((site / "runs" / "mo-40" / "index.html").read_text(encoding="utf-8"))
    trials = [a for a in page.all("a") if (a.get("href") or "").startswith("trials/")]
    assert len(trials) == 40
    assert len(page.all("img")) == len(list((site / "runs" / "mo-40" / "figures").glob("*.png"))) >= 5
    text = "".join(page.text)
    assert "not a measurement of an LLM" in text and "MOER [95%]" in text
    assert {"id": "filter", "type": "search", "placeholder": "cell, outcome, collision..."} in page.all("input")
    # the report's tables, each under its heading, as text
    assert "The report's tables" in text and "Outcomes and collisions per cell" in text
    assert "Refusals and attacks per cell" in text and "Against the paper" in text
    assert len(page.all("table")) >= 1 + 5 + 1


def test_a_trial_page_shows_each_step_with_what_the_llm_saw_and_said(runs_dir, site):
    from safeembodai_plugins.state.sqlite_db import SqliteStateStore

    store = SqliteStateStore(runs_dir / "mo-40" / "results.sqlite", readonly=True)
    trials = [r for r in store.results() if r.spec.arm == "safeembodai" and r.spec.condition == "attack"]
    trial = max(trials, key=lambda r: (r.interventions, r.steps))
    records = store.steps(trial.spec.trial_id)
    html = (site / "runs" / "mo-40" / "trials" / (trial.spec.trial_id.replace("/", "__") + ".html")).read_text()
    page = Page(html)
    steps = [attrs for attrs in page.all("li") if attrs.get("class") == "step"]
    assert len(steps) == len(records) == trial.steps
    images = [a for a in page.all("img") if a.get("class") != "plans"]
    assert len(images) == 1 + 2 * len(records)  # the trajectory, then camera and LiDAR per step
    parsed = sum(any(a.response is not None for a in r.attempts) for r in records)
    assert sum(1 for a in page.all("img") if a.get("class") == "plans") == parsed  # each step's plans drawn
    assert sum(1 for a in images if a.get("alt") == "camera_image") == len(records)
    assert html.count("<details><summary>prompt</summary>") == len(records)
    text = "".join(page.text)
    assert text.count("attack injected") == sum(len(r.attacks) for r in records)
    attempts = [a for r in records for a in r.attempts]
    assert len([t for t, attrs in page.tags if t == "div" and "attempt" in (attrs.get("class") or "")]) == len(attempts)
    for attempt in attempts:
        for verdict in attempt.verdicts:
            if not verdict.valid:
                assert f"{verdict.rule}" in text and verdict.reason.split(";")[0][:60] in text


def test_rebuilding_renders_only_what_changed(runs_dir, tmp_path):
    source = tmp_path / "runs"
    shutil.copytree(runs_dir / "hostile", source / "hostile")
    out = tmp_path / "site"
    assert build_site(source, out) == {"found": 1, "runs": 1, "trials": 4, "skipped": []}
    assert build_site(source, out) == {"found": 1, "runs": 0, "trials": 0, "skipped": []}
    shutil.copytree(runs_dir / "mo-40", source / "mo-40")
    assert build_site(source, out) == {"found": 2, "runs": 1, "trials": 40, "skipped": []}
    manifest = json.loads((out / "manifest.json").read_text())
    assert set(manifest["runs"]) == {"hostile", "mo-40"}
    assert "hostile" in (out / "index.html").read_text()  # a run not rendered again keeps its row


def test_runs_one_level_down_are_found_and_a_folder_without_runs_is_an_error(runs_dir, tmp_path, capsys):
    from safeembodai_core.cli import main

    source = tmp_path / "runs"
    shutil.copytree(runs_dir / "hostile", source / "mo-study" / "hostile")  # ablate --out runs/mo-study
    shutil.copytree(runs_dir / "hostile", source / "hostile")  # the same name at the top: both kept apart
    out = tmp_path / "site"
    assert build_site(source, out)["found"] == 2
    assert set(json.loads((out / "manifest.json").read_text())["runs"]) == {"hostile", "mo-study/hostile"}
    assert (out / "runs" / "mo-study-hostile" / "index.html").is_file()
    empty = tmp_path / "empty"
    (empty / "quickstart-run-1").mkdir(parents=True)  # a 'safeembodai run' folder: one trial, not a run
    (empty / "quickstart-run-1" / "trial.json").write_text("{}")
    with pytest.raises(SystemExit) as done:
        main(["view", str(empty), "--out", str(tmp_path / "site2")])
    assert done.value.code == 1
    assert "holds no run folder" in capsys.readouterr().err
    assert not (tmp_path / "site2").exists()  # nothing written


def test_a_broken_run_folder_gets_a_row_with_its_error_and_hides_nothing(runs_dir, tmp_path, cli_runner):
    source = tmp_path / "runs"
    shutil.copytree(runs_dir / "hostile", source / "hostile")
    (source / "broken").mkdir()
    (source / "broken" / "scenario.json").write_text("{not json", encoding="utf-8")
    done = cli_runner.invoke(cli, ["view", str(source), "--out", str(tmp_path / "site")])
    assert done.exit_code == 0, done.output
    text = "".join(Page((tmp_path / "site" / "index.html").read_text()).text)
    assert "unreadable" in text and "broken" in text and "hostile" in text


def test_status_says_running_interrupted_or_finished(runs_dir, tmp_path):
    from safeembodai_core.runs.folder import RunLock
    from safeembodai_core.view.runs import running

    folder = tmp_path / "hostile"
    shutil.copytree(runs_dir / "hostile", folder)
    assert not running(folder)
    lock = RunLock(folder, wait_s=0.0)
    lock.acquire()
    try:
        assert running(folder)
        build_site(folder, tmp_path / "site")
        assert "running" in (tmp_path / "site" / "index.html").read_text()
    finally:
        lock.release()
    import sqlite3

    with sqlite3.connect(folder / "results.sqlite") as db:
        db.execute("update trials set status = 'running', result = NULL where trial_index = 0 and arm = 'baseline' "
                   "and condition = 'attack'")
    build_site(folder, tmp_path / "site2")
    assert "interrupted" in (tmp_path / "site2" / "index.html").read_text()


def test_pages_shared_with_a_helper_process_are_the_pages_rendered_here(repo, tmp_path, monkeypatch):
    """``view`` builds with ``parallel``: a spawned helper renders a share of a run's trial pages
    with the installed plugins and a runner of its own; the site is the same, byte for byte."""
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario
    from safeembodai_core.view import site as site_module

    plugins = load_plugins(environ={})
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=2"], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(tmp_path / "run"))
    try:
        ablation.run()
    finally:
        ablation.close()
    build_site(tmp_path / "run", tmp_path / "here")
    monkeypatch.setattr(site_module, "helpers_for", lambda pages: 1)
    shared = []
    real = site_module._render_trial
    monkeypatch.setattr(site_module, "_render_trial", lambda *args, **kwargs: shared.append(1) or real(*args, **kwargs))
    counts = build_site(tmp_path / "run", tmp_path / "shared", parallel=True)
    assert counts["trials"] == 4 and len(shared) == 2  # two here, two in the helper
    here = {p.relative_to(tmp_path / "here"): p.read_bytes() for p in (tmp_path / "here").rglob("*") if p.is_file()}
    there = {p.relative_to(tmp_path / "shared"): p.read_bytes() for p in (tmp_path / "shared").rglob("*")
             if p.is_file()}
    assert here.keys() == there.keys() and len(here) > 10
    assert [name for name in here if here[name] != there[name]] == []
