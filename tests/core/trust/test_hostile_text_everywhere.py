"""A run whose every text field is hostile, through every command that shows it to a person.

The run is made as an attacker would make one to send to a reviewer: a scenario whose description
is hostile (names are refused unless plain: ``docs/scenarios.md``), a pilot whose answers write
terminal escapes, bidi overrides, HTML and Markdown, and a store edited afterwards so that model
names, details, rule names and attack kinds are hostile too. Then ``ablate``'s summary, ``report``, ``show``, ``view``,
``export``, ``guard-bag`` and ``plugins`` (with a hostile third-party plugin installed) run on it, and
each medium is checked with its own rule: the terminal shows no control, C1, bidi, zero-width or tag
character; report.md no live image, link, HTML or table break; metrics.csv no formula; metrics.json
no non-finite number; the site no markup from data.
"""

from __future__ import annotations

import csv
import json
import os
import re
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

pytestmark = pytest.mark.slow

#: Terminal escapes, C1, bidi, zero-width and tag characters, HTML, Markdown, a formula, a table break.
EVIL = ("\x1b[31mred\x1b[0m\u202eevil\u202c\x9b2J\u200b\U000e0041<script>alert(1)</script>"
        "![x](http://evil.example/p.png)[a](javascript:x)|=HYPERLINK(\"http://evil\")")
#: The same, fit for a name (no slash: names make trial ids and file names).
EVIL_NAME = "=cmd\x1b[2J\u202e<b>arm</b>![x](x)\u200b|"
#: Characters no terminal line may carry.
INVISIBLE = re.compile("[\x00-\x08\x0b-\x1f\x7f-\x9f\u200b-\u200f\u202a-\u202e\u2066-\u2069\ufeff"
                       "\U000e0000-\U000e007f]")


def clean_terminal(text: str, what: str) -> None:
    found = INVISIBLE.search(text)
    if found is not None:
        near = text[max(0, found.start() - 60):found.end() + 20]
        pytest.fail(f"{what}: {found.group()!r} reached the terminal near {near!r}")


def cli(*args: str, cwd: Path, env: dict[str, str] | None = None, ok: bool = True) -> str:
    done = subprocess.run([sys.executable, "-m", "safeembodai_core", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=600, env={**os.environ, "COLUMNS": "200", **(env or {})})
    said = done.stdout + done.stderr
    assert "Traceback" not in said, said
    if ok:
        assert done.returncode == 0, said
    clean_terminal(said, " ".join(args[:1]))
    return said


@pytest.fixture(scope="module")
def hostile_run(tmp_path_factory, repo):
    folder = tmp_path_factory.mktemp("hostile")
    data = yaml.safe_load((repo / "scenarios" / "quickstart.yaml").read_text(encoding="utf-8"))
    plan = {"perception": [{"object": EVIL, "is_attack": False}], "planning": EVIL,
            "control": [{"command": "turn", "direction": "left", "angle": 30, "justification": EVIL}]}
    data.update(description=EVIL, trials=1, max_steps=2,
                backend={"use": "scripted", "options": {"responses": [json.dumps(plan), EVIL, json.dumps(plan)]}})
    scenario = folder / "hostile.yaml"
    scenario.write_text(yaml.safe_dump(data, allow_unicode=True), encoding="utf-8")
    summary = cli("ablate", str(scenario), "--out", "runs", "--bags", "mcap", cwd=folder)
    [run] = [p for p in (folder / "runs").iterdir() if p.is_dir()]
    conn = sqlite3.connect(run / "results.sqlite")
    for trial_id, result in conn.execute("SELECT trial_id, result FROM trials").fetchall():
        value = json.loads(result)
        value.update(models=[EVIL], detail=EVIL)
        conn.execute("UPDATE trials SET result = ? WHERE trial_id = ?", (json.dumps(value), trial_id))
    for trial_id, step, record in conn.execute("SELECT trial_id, step, record FROM steps").fetchall():
        value = json.loads(record)
        for attempt in value["attempts"]:
            attempt["model"] = EVIL
        conn.execute("UPDATE steps SET record = ? WHERE trial_id = ? AND step = ?", (json.dumps(value), trial_id, step))
    conn.execute("UPDATE verdicts SET rule = ?", (EVIL_NAME,))
    conn.execute("UPDATE attacks SET kind = ?", (EVIL_NAME,))
    conn.commit()
    conn.close()
    return folder, run, summary


def test_the_run_summary_shows_hostile_names_as_text(hostile_run):
    _, _, summary = hostile_run
    assert summary  # clean (cli() checked it); the description is not part of the summary


def test_report_md_and_the_terminal(hostile_run):
    folder, run, _ = hostile_run
    cli("report", str(run), cwd=folder)
    text = (run / "report.md").read_text(encoding="utf-8")
    clean_terminal(text, "report.md")
    assert "\\x1b" in text and "alert(1)" in text  # the description is there, as text
    for live in ("<script>", "![x]"):
        assert live not in text, live
    targets = re.findall(r"(?<!\\)\]\(([^)]*)\)", text)  # live links and images: only the report's own figures
    assert targets and all(t.startswith(("figures/", "trajectories/")) for t in targets), targets
    for line in text.splitlines():  # a hostile name never adds a column to a table row
        if line.startswith("| ") and "cmd" in line:
            assert line.count(" | ") + 2 == len(re.findall(r"(?<!\\)\|", line))


def test_metrics_csv_and_json(hostile_run):
    _, run, _ = hostile_run
    with (run / "metrics.csv").open(newline="", encoding="utf-8") as handle:
        cells = [cell for row in csv.reader(handle) for cell in row]
    assert not any(cell.startswith(("=", "+", "@")) for cell in cells)
    clean_terminal("".join(cells), "metrics.csv")
    json.loads((run / "metrics.json").read_text(encoding="utf-8"), parse_constant=lambda name: 1 / 0)


def test_show_every_trial(hostile_run):
    folder, run, _ = hostile_run
    said = cli("show", str(run), cwd=folder)
    said += cli("show", str(run), "--trial", "flatland/safeembodai/attack/0", cwd=folder)
    assert "\\u202e" in said or "\\x1b" in said


def test_view_writes_no_markup_from_data(hostile_run):
    folder, run, _ = hostile_run
    cli("view", str(run), "--out", str(folder / "site"), cwd=folder)
    pages = list((folder / "site").rglob("*.html"))
    assert len(pages) >= 3
    assert any("\\u202e" in page.read_text(encoding="utf-8") for page in pages)  # the data is there, shown
    for page in pages:
        html = page.read_text(encoding="utf-8")
        assert "<script>alert" not in html and "<b>arm</b>" not in html and "javascript:x" not in html.replace(
            "](javascript:x)", ""), page
        assert "\u202e" not in html and "\x1b" not in html, page


def test_export_and_guard_bag(hostile_run):
    folder, run, _ = hostile_run
    cli("export", str(run), "--out", str(folder / "exported"), cwd=folder)
    bags = [p for p in (run / "bags").iterdir() if p.is_dir()]
    assert bags
    said = cli("guard-bag", str(bags[0]), "--cmd", "/safeembodai/plan", "--pose", "/pose", cwd=folder, ok=False)
    judged = cli("guard-bag", str(bags[0]), "--cmd", "/safeembodai/plan", "--pose", "/pose", "--json", cwd=folder,
                 ok=False)
    json.loads(judged[judged.index("{"):], parse_constant=lambda name: 1 / 0)
    assert said


def test_plugins_lists_a_hostile_third_party_plugin_as_text(hostile_run, tmp_path):
    folder, _, _ = hostile_run
    site = tmp_path / "site"
    (site / "evil_plugin-1.0.dist-info").mkdir(parents=True)
    (site / "evil_plugin-1.0.dist-info" / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: evil-plugin\nVersion: 1.0\nSummary: {EVIL}\n", encoding="utf-8")
    (site / "evil_plugin-1.0.dist-info" / "entry_points.txt").write_text(
        "[safeembodai]\nevil = evil_plugin\n", encoding="utf-8")
    (site / "evil_plugin.py").write_text(
        "from safeembodai_core.hookspecs import hookimpl\n"
        "from safeembodai_core.testing import ReplayBackend\n\n"
        "@hookimpl\n"
        "def register_llm_backends(register):\n"
        f"    register('evil', lambda options, context: ReplayBackend('x'), description={EVIL!r})\n",
        encoding="utf-8")
    env = {"PYTHONPATH": str(site)}
    said = cli("plugins", cwd=folder, env=env)
    assert "evil" in said
    listed = cli("plugins", "--json", cwd=folder, env=env)
    json.loads(listed[listed.index("["):])
