"""Each step's plans drawn where they would have gone, on the trial page (issue 38): a static SVG,
accepted green, refused red with the return in its way circled, rule names escaped."""

from __future__ import annotations

import re

from safeembodai_core.models import Attempt, Verdict, parse_response
from safeembodai_core.testing import CorridorWorld, answer, straight, turn
from safeembodai_core.view.plan_picture import GREEN, RED, plan_svg


def _attempt(index, text, *verdicts):
    return Attempt(index=index, raw_text=text, response=parse_response(text), verdicts=list(verdicts))


def test_a_refused_straight_is_red_with_the_wall_return_circled_and_an_accepted_plan_green():
    scan = CorridorWorld(wall_mm=600).scan()
    refused = _attempt(0, answer(straight(399)), Verdict(rule='<b>"wall"</b>', valid=False, reason="too close",
                                                           signal_index=0))
    accepted = _attempt(1, answer(turn(45), straight(100)), Verdict(rule="lidar_clearance", valid=True,
                                                                    signal_index=1))
    svg = plan_svg(scan, [refused, accepted], 170.0)
    assert svg.startswith("<svg") and "<script" not in svg and "<b>" not in svg
    assert "refused by &lt;b&gt;&quot;wall&quot;&lt;/b&gt;" in svg and "attempt 2: accepted" in svg
    lines = re.findall(r'<polyline points="([^"]*)" fill="none" stroke="(#[0-9a-f]+)"', svg)
    assert [colour for _, colour in lines] == [RED, GREEN]
    (x0, y0), (x1, y1) = (tuple(map(float, p.split(","))) for p in lines[0][0].split())
    assert x0 == x1 and y1 < y0  # a straight ahead is drawn up the picture
    circles = re.findall(rf'<circle cx="([\d.]+)" cy="([\d.]+)" r="6" fill="none" stroke="{RED}"', svg)
    assert len(circles) == 1 and float(circles[0][1]) < y1  # the wall's return, beyond where the straight ends


def test_an_answer_that_did_not_parse_draws_no_path():
    broken = Attempt(index=0, raw_text="I will go", parse_error="not JSON")
    assert "polyline" not in plan_svg(CorridorWorld().scan(), [broken], 170.0)


def test_a_trial_page_shows_each_steps_plans_picture(repo, tmp_path):
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario
    from safeembodai_core.view.site import build_site

    plugins = load_plugins(environ={})
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", [
        "trials=1", "max_steps=3", "backend={use: mock, options: {ignore_clearance_p: 0.9}}"], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(tmp_path / "run"))
    try:
        ablation.run()
    finally:
        ablation.close()
    build_site(tmp_path / "run", tmp_path / "site", plugins)
    pages = list((tmp_path / "site").rglob("trials/*.html"))
    pictures = list((tmp_path / "site").rglob("*-plans.svg"))
    assert pages and pictures
    assert all('class="plans"' in page.read_text(encoding="utf-8") for page in pages)
    assert all(p.read_text(encoding="utf-8").startswith("<svg") for p in pictures)


def test_the_points_drawn_at_once_read_as_one_at_a_time_would():
    """The SVG's coordinates, computed all at once (issue 50: the dots were most of view's own time),
    are the same text a float64's ``round`` of each point gave: halves, negative zero, far points."""
    import numpy as np

    from safeembodai_core.view.plan_picture import SIZE_PX, _screen

    rng = np.random.default_rng(50)
    points = np.concatenate([rng.uniform(-6000, 6000, (4000, 2)), np.arange(-800, 800).reshape(-1, 2) / 40,
                             [[0.0, -0.0], [1e-9, -1e-9], [1800.0, -1800.0]]])
    for scale in (SIZE_PX / 3000, SIZE_PX / 5000, SIZE_PX / (2 * 1733.3)):
        one_at_a_time = [f"{round(SIZE_PX / 2 - p[1] * scale, 1)},{round(SIZE_PX / 2 - p[0] * scale, 1)}"
                         for p in points]
        assert [f"{x},{y}" for x, y in _screen(points, scale)] == one_at_a_time
    assert _screen(np.zeros((0, 2)), 0.1) == [] and _screen(np.array([]), 0.1) == []
