"""Reports: metrics files, figures, and the comparison with the paper's published values."""

from __future__ import annotations

import pytest
import csv
import json

from safeembodai_core.models import Outcome, TrialResult, TrialSpec
from safeembodai_core.report import write_report
from safeembodai_core.report.paper import paper_value
from safeembodai_core.scenario import parse_scenario


def results_for(env, arm, condition, outcomes):
    return [TrialResult(spec=TrialSpec(trial_id=f"{env}/{arm}/{condition}/{i}", environment=env, arm=arm,
                                       condition=condition, index=i, seed=i),
                        outcome=Outcome(o), steps=s, prompt_tokens=1000 * s, distance_mm=150.0 * s)
            for i, (o, s) in enumerate(outcomes)]


def test_paper_values_ship_as_data():
    assert paper_value("moer", "OF", "safeembodai", "no_attack") == 1.0
    assert paper_value("moer", "MO", "baseline", "attack") == 0.12
    assert paper_value("steps", "SO", "baseline", "attack") is None  # no completed trial in the paper
    assert paper_value("moer", "flatland", "baseline", "attack") is None


@pytest.mark.slow
def test_report_writes_metrics_figures_and_a_paper_comparison(tmp_path):
    scenario = parse_scenario("name: t\nmax_steps: 20\nenvironments: [OF]\n", "t.yaml")
    results = (results_for("OF", "baseline", "no_attack", [("completed", 7), ("timeout", 20), ("completed", 8)])
               + results_for("OF", "safeembodai", "no_attack", [("completed", 9)] * 3))
    report = write_report(tmp_path, scenario, results)
    text = report.read_text()
    assert "| OF | baseline | no_attack | 3 |" in text
    assert ("## Against the paper" in text
            and "| OF | safeembodai | no_attack | moer | 1.00 [1.00, 1.00] | 1 | yes |" in text)
    rows = list(csv.DictReader((tmp_path / "metrics.csv").open()))
    baseline = next(r for r in rows if r["arm"] == "baseline")
    assert float(baseline["moer"]) == (1 + 0.6 + 1) / 3 and baseline["s_max_from"] == "timeouts"
    assert json.loads((tmp_path / "metrics.json").read_text())["scenario"] == "t"
    for name in ("moer", "adr", "tlr", "steps", "tokens", "distance_mm"):
        assert (tmp_path / "figures" / f"{name}.png").read_bytes()[:4] == b"\x89PNG"
