"""The trial page and the run page show struck collisions apart: while the robot stood, and during
its own motion (issue 39); a run recorded before the split says nothing it does not know."""

from __future__ import annotations

from types import SimpleNamespace

from safeembodai_core.models import Outcome, TrialResult, TrialSpec
from safeembodai_core.view.html import render
from safeembodai_core.view.runs import TrialRow

RUN = SimpleNamespace(name="r", simulated="", backend="b", model="m", seed=0, trials_per_cell=1, finished=1,
                      total=1, status="finished", cells=[], trials=[], figures=[], nodes=[], report=None,
                      page="r", error=None, started="", scenario="s", refresh=0, tables=[], left_out=[])


def _result(standing):
    spec = TrialSpec(trial_id="DO/moving/no_attack/0", environment="DO", arm="moving", condition="no_attack",
                     index=0, seed=1)
    return TrialResult(spec=spec, outcome=Outcome.INTERRUPTED, steps=3, collisions=3, collisions_struck=3,
                       collisions_struck_standing=standing)


def test_the_trial_page_splits_struck_collisions():
    page = render("trial.html.j2", run=RUN, result=_result(1), steps=[], trajectory=None, recording=None,
                  missing=None, left_out=[], refresh=0)
    assert "3 struck (1 standing, 2 moving)" in page
    older = render("trial.html.j2", run=RUN, result=_result(None), steps=[], trajectory=None, recording=None,
                   missing=None, left_out=[], refresh=0)
    assert "3 struck;" in older and "standing" not in older


def test_the_run_page_says_how_many_struck_while_standing():
    row = TrialRow("DO/moving/no_attack/0", "t.html", "DO", "moving", "no_attack", 0, "interrupted", 3, 0, 0, 3, "",
                   struck_standing=1)
    page = render("run.html.j2", run=SimpleNamespace(**{**vars(RUN), "trials": [row]}), refresh=0)
    assert "3 (1 standing)" in page
