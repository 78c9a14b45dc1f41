"""metrics.csv and metrics.json from hostile scenario names: no spreadsheet formula, no control
character, no JSON that standard readers refuse."""

from __future__ import annotations

import csv
import json
import math

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.report import write_report
from safeembodai_core.scenario import load_scenario
from safeembodai_core.trust.text import csv_cell, json_ready


def test_csv_cells_that_start_like_a_formula_are_text_numbers_stay_numbers():
    assert csv_cell("=HYPERLINK(\"http://evil\")") == "'=HYPERLINK(\"http://evil\")"
    assert [csv_cell(v) for v in ("+1", "-cmd", "@SUM(A1)")] == ["'+1", "'-cmd", "'@SUM(A1)"]
    assert [csv_cell(v) for v in ("\tx", "\rx")] == ["\\tx", "\\rx"]  # shown as escapes: no longer a formula
    assert csv_cell("arm\x1b[2J") == "arm\\x1b[2J"  # shown, not obeyed
    assert csv_cell(-0.25) == -0.25 and csv_cell(3) == 3 and csv_cell(None) is None
    assert csv_cell(math.nan) == "" and csv_cell(math.inf) == ""


def test_json_ready_leaves_no_non_finite_number():
    value = {"a": [1.0, math.nan, {"b": -math.inf}], "c": (math.inf, "x")}
    assert json.loads(json.dumps(json_ready(value), allow_nan=False)) == {"a": [1.0, None, {"b": None}],
                                                                         "c": [None, "x"]}


def _run_and_report(scenario, plugins, folder):
    """Run ``scenario`` into ``folder`` and write its report there."""
    ablation = Ablation(scenario, plugins, RunFolder(folder))
    try:
        write_report(folder, scenario, ablation.run(), store=ablation.store, plugins=plugins)
    finally:
        ablation.close()


def _hostile_arm(repo, plugins, arm: str, **update):
    """quickstart (1 trial, 2 steps) with its baseline arm renamed ``arm`` and ``update`` applied."""
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=2"], plugins.registry)
    arms = {(arm if name == "baseline" else name): value for name, value in scenario.arms.items()}
    return scenario.model_copy(update={"arms": arms, **update})


def test_a_run_with_a_formula_for_an_arm_name_writes_inert_files(repo, plugins, tmp_path):
    scenario = _hostile_arm(repo, plugins, "=cmd|' /C calc'!A0")
    _run_and_report(scenario, plugins, tmp_path)
    with (tmp_path / "metrics.csv").open(newline="", encoding="utf-8") as handle:
        cells = [cell for row in csv.reader(handle) for cell in row]
    assert "'=cmd|' /C calc'!A0" in cells
    assert not any(cell.startswith(("=", "+", "@")) for cell in cells)
    json.loads((tmp_path / "metrics.json").read_text(), parse_constant=lambda name: 1 / 0)  # no NaN/Infinity


def test_every_name_from_data_in_report_md_is_inert_markdown(repo, plugins, tmp_path):
    """Scenario names, description and a store's rule names can carry an image, a link, HTML or a
    table break; report.md shows them as text."""
    hostile = "![px](http://evil.example/p.png)<img src=x>[a](javascript:x)|`"
    scenario = _hostile_arm(repo, plugins, hostile, description="# " + hostile + "\n\x1b[2J", name="q" + hostile)
    _run_and_report(scenario, plugins, tmp_path)
    report = (tmp_path / "report.md").read_text()
    import re

    outside_code = re.sub(r"`[^`\n]*`", "", report)  # inside a code span Markdown is literal text
    for active in (r"(?<!\\)!(?=\[px)", r"(?<!\\)<img", r"(?<!\\)\[a(?<!\\)\]"):  # unescaped image, HTML, link
        assert re.search(active, outside_code) is None, active
    assert "\x1b" not in report
    assert "\\!\\[px\\](http://evil.example/p.png)\\<img src=x\\>" in report
    assert report.splitlines()[0].startswith("# q\\!\\[px\\]")
    tables: list[list[str]] = [[]]
    for line in report.splitlines():  # no row gained a column from a name's |
        if line.startswith("|"):
            tables[-1].append(line)
        elif tables[-1]:
            tables.append([])
    for table in filter(None, tables):
        widths = {len(re.findall(r"(?<!\\)\|", row)) for row in table}
        assert len(widths) == 1, table
