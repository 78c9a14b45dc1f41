"""Where a Ray run's trials ran: report.md and the run page count trials per node (nothing is said for
a run on this machine only), and a hostile node name stays text."""

from __future__ import annotations

from pathlib import Path

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.report import write_report
from safeembodai_core.report.markdown import nodes
from safeembodai_core.scenario import load_scenario
from safeembodai_core.view import build_site

REPO = Path(__file__).resolve().parents[3]


def _run_on_nodes(folder: Path, names: list[str | None]) -> None:
    """A small run whose trials are then recorded as run on ``names`` in turn (as the relay records them)."""
    plugins = load_plugins(environ={})
    scenario = load_scenario(REPO / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=2"], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(folder))
    try:
        results = ablation.run()
        results = [r.model_copy(update={"node": names[k % len(names)]}) for k, r in enumerate(results)]
        for result in results:
            ablation.store.end_trial(result)
        write_report(folder, scenario, results, store=ablation.store, plugins=plugins)
    finally:
        ablation.close()


def test_report_and_run_page_count_trials_per_node(tmp_path):
    _run_on_nodes(tmp_path / "runs" / "on-ray", ["10.0.0.1/aaaa0001", "10.0.0.2/bbbb0002", "10.0.0.2/bbbb0002",
                                                  "<b>x</b>/\u202e"])
    report = (tmp_path / "runs" / "on-ray" / "report.md").read_text()
    assert "**Ran on:** 3 nodes (`10.0.0.1/aaaa0001` 1, `10.0.0.2/bbbb0002` 2," in report
    build_site(tmp_path / "runs", tmp_path / "site")
    page = next((tmp_path / "site").rglob("on-ray*/index.html")).read_text()
    assert "<h2>Ran on</h2>" in page and "10.0.0.2/bbbb0002</td><td>2</td>" in page
    assert "<b>x</b>" not in page  # a node's name is text


def test_nothing_is_said_of_nodes_for_a_run_on_this_machine(tmp_path):
    _run_on_nodes(tmp_path / "runs" / "here", [None])
    assert "Ran on" not in (tmp_path / "runs" / "here" / "report.md").read_text()
    build_site(tmp_path / "runs", tmp_path / "site")
    assert "Ran on" not in next((tmp_path / "site").rglob("here*/index.html")).read_text()
    assert nodes([]) == []
