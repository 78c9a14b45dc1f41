"""The metric catalog: one entry (name, label, digits, figure, console column, Inspect scorer and a
compute function) is all a new metric takes -- the metrics files, report.md, the figures, the
terminal summary and the Inspect scorers all show it -- and a plugin adds one through the
``register_metrics`` hook."""

from __future__ import annotations

import csv
import json

import pytest
from rich.console import Console

from safeembodai_core.errors import PluginError
from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.metrics import CellTrials, Estimate, Metric, cell_metrics, metric_catalog, wilson
from safeembodai_core.models import Outcome, TrialResult, TrialSpec
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.report import write_report
from safeembodai_core.scenario import parse_scenario

SCENARIO = """
name: catalogued
trials: 4
environments: [OF]
"""


def _long(cell: CellTrials) -> Estimate:
    """Trials that took more than 5 steps / scored trials."""
    return wilson(sum(r.steps > 5 for r in cell.scored), len(cell.scored))


LONG = Metric("long_trials", "long trials", _long, "trials of more than 5 steps", interval="wilson",
              console="long", figure="long_trials", axis="Trials of more than 5 steps")


class LongTrials:
    @hookimpl
    def register_metrics(self, register):
        register(LONG)


def _results() -> list[TrialResult]:
    """OF, both arms, both conditions, four trials per cell: 2 of baseline's 4 and 1 of safeembodai's run long."""
    results = []
    for condition in ("no_attack", "attack"):
        for arm, steps in (("baseline", (3, 8, 9, 4)), ("safeembodai", (3, 4, 6, 2))):
            for k, s in enumerate(steps):
                spec = TrialSpec(trial_id=f"OF/{arm}/{condition}/{k}", environment="OF", arm=arm,
                                 condition=condition, index=k, seed=k)
                results.append(TrialResult(spec=spec, outcome=Outcome.COMPLETED, steps=s))
    return results


@pytest.fixture(scope="module")
def plugins():
    return load_plugins([("long_trials_plugin", LongTrials())], environ={})


def test_a_plugin_metric_joins_the_catalog_after_the_built_ins_with_its_plugin_named(plugins):
    catalog = plugins.metrics
    assert catalog[:len(metric_catalog())] == metric_catalog()
    assert catalog[-1].name == "long_trials" and catalog[-1].origin == "long_trials_plugin"
    assert metric_catalog(plugins) == catalog


@pytest.mark.slow
def test_a_plugin_metric_is_in_the_metrics_files_the_report_the_figures_and_the_console(plugins, tmp_path):
    from safeembodai_core.cli.summary import summary_table

    scenario = parse_scenario(SCENARIO, "catalogued.yaml", registry=plugins.registry)
    results = _results()
    report = write_report(tmp_path, scenario, results, plugins=plugins).read_text()
    cells = {(c["arm"], c["condition"]): c for c in json.loads((tmp_path / "metrics.json").read_text())["cells"]}
    assert (cells[("baseline", "attack")]["long_trials"] == 0.5
            and cells[("safeembodai", "attack")]["long_trials"] == 0.25)
    expected = wilson(2, 4)
    assert (cells[("baseline", "attack")]["long_trials_low"], cells[("baseline", "attack")]["long_trials_high"]) == (
        expected.low, expected.high)
    with (tmp_path / "metrics.csv").open() as handle:
        rows = list(csv.DictReader(handle))
    assert {row["long_trials"] for row in rows} == {"0.5", "0.25"} and "long_trials_n" in rows[0]
    header = next(line for line in report.splitlines() if line.startswith("| env | arm | condition | n |"))
    assert header.endswith("| long trials |")
    assert "| OF | baseline | attack | 4 |" in report and f"| {expected.fmt()} |" in report
    assert "long trials: trials of more than 5 steps (wilson interval; metric `long_trials` of the plugin " \
           "`long_trials_plugin`)." in report
    assert (tmp_path / "figures" / "long_trials.png").is_file() and "![long_trials](figures/long_trials.png)" in report
    console = Console(record=True, width=120)
    console.print(summary_table(scenario, results, plugins=plugins))
    text = console.export_text()
    assert " long " in text and "long = trials of more than 5 steps (plugin long_trials_plugin)" in text
    row = next(line for line in text.splitlines() if line.startswith("OF") and "baseline" in line and "attack" in line
               and "no_attack" not in line)
    assert row.split()[-2] == "0.50"  # the long column, before err


def test_a_plugin_metric_is_an_inspect_metric_per_cell(plugins):
    pytest.importorskip("inspect_ai")
    from inspect_ai._util.registry import registry_info, registry_params

    from safeembodai_core.integrations.inspect.scorers import catalog_metric, catalog_scorers
    from safeembodai_core.metrics import MetricSettings

    scorers = catalog_scorers(plugins.metrics, MetricSettings().model_dump(mode="json"), 20, ["attack"])
    names = [registry_info(s).name.rsplit("/", 1)[-1] for s in scorers]
    assert names == ["moer", "outcome", "attack_detection", "collisions", "metrics"]
    metrics = registry_info(scorers[-1]).metadata["metrics"]
    templates = [registry_params(m)["name_template"] for m in metrics]
    assert templates == ["{group_name} long_trials", "{group_name} long_trials low", "{group_name} long_trials high"]

    import asyncio
    from types import SimpleNamespace

    from inspect_ai.scorer import SampleScore

    from safeembodai_core.integrations.inspect.solver import RESULT_KEY

    baseline = [r for r in _results() if (r.spec.arm, r.spec.condition) == ("baseline", "attack")]
    samples = [SampleScore(score=asyncio.run(scorers[-1](SimpleNamespace(store={RESULT_KEY: r.model_dump(mode="json")},
                                                                         metadata={}), None)),
                           sample_id=r.spec.trial_id, sample_metadata={"cell": "OF/baseline/attack"}) for r in baseline]
    assert catalog_metric("long_trials")(samples) == 0.5
    assert catalog_metric("long_trials", "high")(samples) == pytest.approx(wilson(2, 4).high)


def test_cell_metrics_computes_exactly_the_catalog_it_is_given():
    results = [r for r in _results() if (r.spec.arm, r.spec.condition) == ("baseline", "attack")]
    assert cell_metrics(results, 20, catalog=(LONG,)).estimates == {"long_trials": wilson(2, 4)}
    built_in = cell_metrics(results, 20)
    assert [*built_in.estimates] == [entry.name for entry in metric_catalog()]
    assert built_in.moer is built_in.estimates["moer"]
    with pytest.raises(AttributeError, match="no metric 'long_trials'"):
        built_in.long_trials  # noqa: B018 -- not in the catalog it was computed with


class Taken:
    @hookimpl
    def register_metrics(self, register):
        register(Metric("moer", "my MOER", _long))


class NotAMetric:
    @hookimpl
    def register_metrics(self, register):
        register({"name": "x"})


class SameFigure:
    @hookimpl
    def register_metrics(self, register):
        register(Metric("my_tlr", "my TLR", _long, figure="tlr"))


class ColumnOfAnother:
    @hookimpl
    def register_metrics(self, register):
        register(Metric("adr_n", "ADR n", _long))  # a fine name alone, but it writes adr's column


@pytest.mark.parametrize(("plugin", "message"), [
    (Taken(), "metric 'moer' is already defined by safeembodai"),
    (ColumnOfAnother(), "metric 'adr_n' would write the column 'adr_n' of metric 'adr'"),
    (NotAMetric(), "register\\(\\) takes a safeembodai_core.metrics.Metric, got dict"),
    (SameFigure(), "figure 'tlr' is already drawn for metric 'tlr_all'"),
])
def test_a_plugin_metric_that_clashes_or_is_not_a_metric_names_the_plugin(plugin, message):
    plugins = load_plugins([("clashing", plugin)], environ={})
    with pytest.raises(PluginError, match=message) as caught:
        plugins.metrics
    assert caught.value.plugin == "clashing"


@pytest.mark.parametrize("fields", [
    {"name": "Has Space"}, {"name": "trials"}, {"name": "attack_rate"}, {"name": "outcome_completed"},
    {"name": "refusals_total"}, {"name": "self_collision_rate"}, {"digits": 9}, {"interval": "normal"},
    {"figure": "../x"},
    {"label": "two\nlines"}, {"label": "a | b"}, {"compute": 3},
])
def test_a_malformed_metric_is_refused_when_it_is_defined(fields):
    with pytest.raises(ValueError, match="metric"):
        Metric(**{"name": "ok", "label": "ok", "compute": _long, **fields})


def _broken(cell):
    return 1 / 0


@pytest.mark.parametrize(("compute", "message"), [
    (_broken, "metric 'broken' raised ZeroDivisionError"),
    (lambda cell: 0.5, "metric 'broken' returned float, not an Estimate"),
])
def test_a_metric_whose_compute_fails_names_its_plugin(compute, message):
    catalog = (Metric("broken", "broken", compute, origin="sloppy"),)
    with pytest.raises(PluginError, match=message) as caught:
        cell_metrics(_results()[:4], 20, catalog=catalog)
    assert caught.value.plugin == "sloppy"
