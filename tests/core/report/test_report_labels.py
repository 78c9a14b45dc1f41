"""What the figures' legends and the report's header say about the bars: each arm in its own colour
whatever panel is empty, who answered (backend and model, or a simulated pilot), the paper's
diamonds as GPT-4o's."""

from __future__ import annotations

import pytest
from contextlib import contextmanager
from pathlib import Path

from matplotlib.colors import to_rgba

from safeembodai_core.metrics import cell_metrics
from safeembodai_core.models import Outcome, TrialResult, TrialSpec
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.report import write_report
from safeembodai_core.report.figures import draw_figures, figures, metric_figure
from safeembodai_core.report.run_info import run_info
from safeembodai_plugins.backends.litellm.options import model_without_route
from safeembodai_core.scenario import parse_scenario

ARMS = ("baseline", "safeembodai")


def _trial(arm: str, condition: str, index: int, attacked: bool) -> TrialResult:
    spec = TrialSpec(trial_id=f"OF/{arm}/{condition}/{index}", environment="OF", arm=arm, condition=condition,
                     index=index, seed=index)
    return TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=6, attacked_steps=3 if attacked else 0,
                       flagged_steps=index)


def _results() -> list[TrialResult]:
    """OF, both arms, three trials per cell, no_attack first."""
    return [_trial(arm, condition, k, condition == "attack") for condition in ("no_attack", "attack")
            for arm in ARMS for k in range(3)]


def _cells():
    """The cells of :func:`_results`: the first ADR panel (no_attack) has no bars, nothing to detect."""
    results = _results()
    return [cell_metrics([r for r in results if (r.spec.arm, r.spec.condition) == (arm, condition)], 20,
                         attacked=condition == "attack") for condition in ("no_attack", "attack") for arm in ARMS]


@contextmanager
def figure(*args, **kwargs):
    """:func:`metric_figure`, closed afterwards."""
    import matplotlib.pyplot as plt

    fig = metric_figure(*args, **kwargs)
    try:
        yield fig
    finally:
        plt.close(fig)


def _legend(fig):
    assert len(fig.legends) == 1
    legend = fig.legends[0]
    return legend, [text.get_text() for text in legend.get_texts()]


@pytest.mark.slow
def test_each_arm_has_its_own_colour_in_every_legend_even_when_the_first_panel_is_empty(tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    cells = _cells()
    assert all(m.adr.value is None for m in cells if m.condition == "no_attack")  # the empty first panel
    saved = {}
    real = Figure.savefig

    def keep(self, path, **kwargs):
        saved[Path(path).stem] = self
        return real(self, path, **kwargs)

    monkeypatch.setattr(Figure, "savefig", keep)
    draw_figures(cells, tmp_path)
    assert set(saved) == set(figures())
    for name, fig in saved.items():
        legend, labels = _legend(fig)
        colours = {label: to_rgba(handle.get_facecolor()) for handle, label in zip(legend.legend_handles, labels)
                   if label in ARMS}
        assert set(colours) == set(ARMS), name
        assert colours["baseline"] != colours["safeembodai"], name
        # the legend's colour is the colour of the arm's bars
        bars = {to_rgba(patch.get_facecolor()) for axis in fig.axes for patch in axis.patches}
        assert bars <= set(colours.values()), name


def test_the_legend_says_what_the_bars_and_the_diamonds_are():
    with figure(_cells(), "adr", bars="bars: local/SmolLM2, N = 3 trials per cell") as fig:
        legend, labels = _legend(fig)
        assert legend.get_title().get_text() == "bars: local/SmolLM2, N = 3 trials per cell"
        paper = [label for label in labels if "paper" in label]
        assert paper and "GPT-4o" in paper[0] and "diamond" in paper[0]
    with figure(_cells(), "tlr_after_seen", bars="bars: x") as fig:  # no paper value: no diamond entry
        assert not any("paper" in label for label in _legend(fig)[1])


LOCAL_RUN = """
name: localrun
trials: 3
environments: [OF]
backend: {use: local, options: {model: openai/SmolLM2-135M-Instruct}}
"""


def _legend_titles(monkeypatch) -> list[str]:
    """The legend titles of the figures the report draws from now on."""
    titles = []
    real = metric_figure

    def spy(*args, **kwargs):
        fig = real(*args, **kwargs)
        titles.append(fig.legends[0].get_title().get_text())
        return fig

    monkeypatch.setattr("safeembodai_core.report.figures.metric_figure", spy)
    return titles


@pytest.mark.slow
def test_a_local_run_names_the_model_not_litellms_route(tmp_path, monkeypatch):
    plugins = load_plugins(environ={})
    scenario = parse_scenario(LOCAL_RUN, "localrun.yaml", registry=plugins.registry)
    info = run_info(scenario, plugins=plugins)
    assert (info.backend, info.model, info.model_id) == ("local", "SmolLM2-135M-Instruct",
                                                        "openai/SmolLM2-135M-Instruct")
    titles = _legend_titles(monkeypatch)
    text = write_report(tmp_path, scenario, _results(), plugins=plugins).read_text()
    row = next(line for line in text.splitlines() if line.startswith("| model |"))
    assert row.startswith("| model | `SmolLM2-135M-Instruct` (the configured litellm id `openai/SmolLM2-135M-Instruct` "
                          "without its route `openai/`;")
    assert "no reply named a model" in row  # said, not guessed: these results name none
    assert titles == ["bars: local/SmolLM2-135M-Instruct, N = 3 trials per cell"] * len(figures())


@pytest.mark.slow
def test_a_run_whose_replies_named_the_model_is_reported_by_that_name(tmp_path, monkeypatch):
    """The server's own name for the model (each attempt records it, each result collects it) wins
    over the configured id, and the report says where it came from."""
    plugins = load_plugins(environ={})
    scenario = parse_scenario(LOCAL_RUN, "localrun.yaml", registry=plugins.registry)
    results = [r.model_copy(update={"models": ["smollm2-135m-instruct-q4_1"]}) for r in _results()]
    info = run_info(scenario, plugins=plugins, results=results)
    assert info.model == "smollm2-135m-instruct-q4_1"
    assert info.model_source.startswith("as the server named it in its replies")
    titles = _legend_titles(monkeypatch)
    text = write_report(tmp_path, scenario, results, plugins=plugins).read_text()
    assert "| model | `smollm2-135m-instruct-q4_1` (as the server named it" in text
    assert titles[0] == "bars: local/smollm2-135m-instruct-q4_1, N = 3 trials per cell"


def test_the_local_backends_default_model_is_named_local_without_its_route():
    plugins = load_plugins(environ={})
    scenario = parse_scenario("name: t\nenvironments: [OF]\nbackend: local\n", "t.yaml", registry=plugins.registry)
    info = run_info(scenario, plugins=plugins)
    assert (info.model, info.model_id) == ("local", "openai/local")
    assert model_without_route("gpt-4o") == ("gpt-4o", None)
    assert model_without_route("openai/Qwen/Qwen2-VL-7B-Instruct") == ("Qwen/Qwen2-VL-7B-Instruct", "openai")
    assert model_without_route("Qwen/Qwen2-VL-7B-Instruct") == ("Qwen/Qwen2-VL-7B-Instruct", None)


@pytest.mark.slow
def test_the_simulated_pilots_figures_say_it_is_not_an_llm(tmp_path, monkeypatch):
    plugins = load_plugins(environ={})
    scenario = parse_scenario("name: t\ntrials: 3\nenvironments: [OF]\nbackend: mock\n", "t.yaml",
                              registry=plugins.registry)
    titles = _legend_titles(monkeypatch)
    write_report(tmp_path, scenario, _results(), plugins=plugins)
    assert titles == ["bars: simulated pilot (mock), not an LLM, N = 3 trials per cell"] * len(figures())


def test_an_empty_panel_says_there_is_nothing_to_estimate():
    figure = metric_figure(_cells(), "adr")
    try:
        first, second = figure.axes[:2]
        assert [t.get_text() for t in first.texts] == ["n/a: nothing to estimate"]  # no attacks: no ADR
        assert "n/a: nothing to estimate" not in [t.get_text() for t in second.texts]
    finally:
        import matplotlib.pyplot as plt

        plt.close(figure)


def test_the_report_names_no_plugin_a_backend_describes_itself(repo):
    """The report's words on a backend come from the backend (its options' ``describe``): the report's
    module and the scenario's describing module list no backend's name, option or route."""
    source = "\n".join((repo / "safeembodai_core" / folder / name).read_text(encoding="utf-8")
                        for folder, name in (("report", "run_info.py"), ("scenario", "describe.py")))
    for plugin_word in ('"mock"', '"scripted"', '"gpt-4o"', '"litellm"', "flag_injection_p", '"openai"'):
        assert plugin_word not in source, plugin_word


def test_a_backend_that_cannot_describe_itself_is_never_taken_for_an_llm(repo, plugins):
    from safeembodai_core.plugin.refs import ComponentRef
    from safeembodai_core.scenario.describe import describe_ref

    gone = describe_ref(ComponentRef(use="a-backend-uninstalled-since", options={"model": "x"}), plugins)
    assert gone.model == "x" and "not known to be an LLM" in gone.simulated
    stale = describe_ref(ComponentRef(use="mock", options={"no_such_option": 1}), plugins)
    assert "not known to be an LLM" in stale.simulated


def test_a_backend_name_from_a_run_folder_reaches_the_report_as_text(plugins, tmp_path):
    """The banner of a backend that cannot describe itself names it: escaped for Markdown and the terminal."""
    from safeembodai_core.plugin.refs import ComponentRef
    from safeembodai_core.report.markdown import header
    from safeembodai_core.report.run_info import RunInfo
    from safeembodai_core.scenario.describe import describe_ref

    hostile = ComponentRef(use="x<img src=x onerror=alert(1)>![p](http://evil/p.png)\x1b[2J\u202e",
                           options={"model": "m\x1b]8;;"})
    described = describe_ref(hostile, plugins)
    assert "\x1b" not in described.simulated and "\u202e" not in described.simulated
    info = RunInfo(backend="x", model="m", seed=0, fingerprint="f", trials_per_cell=1, simulated=described.simulated,
                   why=described.why, pilot_words=described.pilot)
    from safeembodai_core.scenario import parse_scenario

    text = "\n".join(header(parse_scenario("name: t\nenvironments: [OF]\nstate: memory\n", "t.yaml"), info, 0))
    import re

    assert re.search(r"(?<!\\)<img", text) is None and "![p](" not in text  # shown as escaped text
    assert "not known to be an LLM" in text
    assert "Whether an LLM answered is not known" in text and info.pilot.endswith("(not known to be an LLM)")


def test_a_describe_that_fails_is_a_backend_not_known_to_be_an_llm(plugins):
    from safeembodai_core.contracts.descriptions import BackendOptions
    from safeembodai_core.hookspecs import hookimpl
    from safeembodai_core.plugin.refs import ComponentRef
    from safeembodai_core.scenario.describe import describe_ref
    from safeembodai_core.testing import inline_plugins

    class Broken(BackendOptions):
        def describe(self):
            raise RuntimeError("boom")

    class Plugin:
        @hookimpl
        def register_llm_backends(self, register):
            register("broken", lambda options, context: None, options=Broken)

    described = describe_ref(ComponentRef(use="broken"), inline_plugins(("p", Plugin())))
    assert "its describe() failed: RuntimeError: boom" in described.simulated


def test_an_option_value_that_is_not_a_number_prints_as_text_and_flatland_names_its_clock(plugins, tmp_path):
    from safeembodai_core.report import write_report
    from safeembodai_core.report.markdown import header
    from safeembodai_core.report.run_info import RunInfo
    from safeembodai_core.scenario import parse_scenario

    scenario = parse_scenario("name: t\nenvironments: [flatland]\nstate: memory\n", "t.yaml", registry=plugins.registry)
    info = RunInfo(backend="b", model="m", seed=0, fingerprint="f", trials_per_cell=1, simulated="a pilot: no LLM",
                   inputs=[("mode", "<b>fast</b>", "what it sets"), ("p", 0.25, "a number")],
                   weaknesses=[("style", "|pipe|")])
    text = "\n".join(header(scenario, info, 0))
    assert "| `mode` | \\<b\\>fast\\</b\\> |" in text and "| `p` | 0.25 |" in text and "`style` \\|pipe\\|" in text
    report = write_report(tmp_path, scenario, [], plugins=plugins).read_text()
    assert "when its room's simulated time runs out, often before the budget: flatland 100 s" in report


def test_an_environment_whose_describe_fails_lists_no_clock_and_the_report_goes_on():
    from safeembodai_core.contracts.descriptions import EnvironmentOptions
    from safeembodai_core.hookspecs import hookimpl
    from safeembodai_core.scenario.describe import describe_environments
    from safeembodai_core.scenario import parse_scenario
    from safeembodai_core.testing import CorridorWorld, inline_plugins

    class Broken(EnvironmentOptions):
        def describe(self):
            raise RuntimeError("boom")

    class Plugin:
        @hookimpl
        def register_environments(self, register):
            register("broken_room", lambda options, context: CorridorWorld(), options=Broken)

    plugins = inline_plugins(("p", Plugin()))
    scenario = parse_scenario("name: t\nenvironments: [broken_room, flatland]\nstate: memory\n", "t.yaml",
                              registry=plugins.registry)
    assert set(describe_environments(scenario, plugins)) == {"flatland"}
