"""Issue 39: no shipped arm is told what only the simulator knows about its world, unless it says so.

A world-private option is declared on its options model (``json_schema_extra=WORLD_PRIVATE``,
:mod:`safeembodai_core.trust.world_private`), not listed here: these tests read the declarations.
"""

from __future__ import annotations

import yaml

from plugins.validators.options import MovingObstaclesOptions
from safeembodai_core.loop.defences import Defences
from safeembodai_core.report.markdown import header
from safeembodai_core.report.run_info import run_info
from safeembodai_core.scenario import load_scenario
from safeembodai_core.trust.world_private import arms_told, private_fields, told_options


def _undeclared(scenario, registry) -> dict[str, list[str]]:
    """Arms that set a world-private option without ``told: true``."""
    return {name: options for name, options in arms_told(scenario, registry).items()
            if options and not scenario.arms[name].told}


def test_no_shipped_arm_names_a_worlds_private_parameter_unless_declared_told(repo, plugins):
    """Every scenario under scenarios/, through the loader: an arm whose options name a world's private
    parameter fails unless it is declared ``told: true`` (an oracle kept for comparison), and an arm
    declared told is told something (the label is not left on a rule that is told nothing)."""
    paths = sorted((repo / "scenarios").glob("*.yaml"))
    assert paths
    for path in paths:
        scenario = load_scenario(path, registry=plugins.registry)
        assert not _undeclared(scenario, plugins.registry), f"{path.name}: told what only the simulator knows"
        for name, arm in scenario.arms.items():
            if arm.told:
                assert told_options(arm, plugins.registry), f"{path.name}: arm {name} says told but is told nothing"


def test_the_shipped_moving_arm_is_told_nothing_and_the_told_arm_is_declared(repo, plugins):
    scenario = load_scenario(repo / "scenarios" / "dynamic.yaml", registry=plugins.registry)
    assert not told_options(scenario.arms["moving"], plugins.registry)
    assert scenario.arms["moving"].fresh_scan and not scenario.arms["moving"].told
    assert scenario.arms["told"].told
    assert set(told_options(scenario.arms["told"], plugins.registry)) == {
        "moving_obstacles.cruise_speed_mm_s", "moving_obstacles.movers_yield_mm", "moving_obstacles.movers_yield_deg"}
    movers = yaml.safe_load((repo / "scenarios" / "movers.yaml").read_text(encoding="utf-8"))
    dynamic = yaml.safe_load((repo / "scenarios" / "dynamic.yaml").read_text(encoding="utf-8"))
    assert dynamic["arms"]["moving"] == movers["arms"]["moving"]


def test_the_check_fails_on_the_told_options_without_the_declaration(repo, plugins, tmp_path):
    """dynamic.yaml as it was before issue 39: its `moving` arm held the told options, undeclared."""
    data = yaml.safe_load((repo / "scenarios" / "dynamic.yaml").read_text(encoding="utf-8"))
    data["arms"]["moving"] = {key: value for key, value in data["arms"].pop("told").items() if key != "told"}
    path = tmp_path / "dynamic.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    scenario = load_scenario(path, registry=plugins.registry)
    assert _undeclared(scenario, plugins.registry) == {"moving": [
        "moving_obstacles.cruise_speed_mm_s", "moving_obstacles.movers_yield_deg", "moving_obstacles.movers_yield_mm"]}


def test_what_is_declared_private():
    """The movers' cruising speed and yielding are the world's; the think time is the robot's own
    planner latency (measurable, and estimated from the observation times when unset), and the rule's
    own bounds and priors are the rule's."""
    assert private_fields(MovingObstaclesOptions) == {"cruise_speed_mm_s", "movers_yield_mm", "movers_yield_deg"}
    assert "think_time_s" not in private_fields(MovingObstaclesOptions)
    schema = MovingObstaclesOptions.model_json_schema()["properties"]
    assert schema["cruise_speed_mm_s"]["world_private"] is True


def test_told_is_recorded_only_when_true_so_old_fingerprints_stay():
    assert "told" not in Defences().model_dump(mode="json")
    assert Defences(told=True).model_dump(mode="json")["told"] is True
    assert Defences.model_validate(Defences(told=True).model_dump(mode="json")).told


def test_report_says_which_arm_was_told(repo, plugins, tmp_path):
    scenario = load_scenario(repo / "scenarios" / "dynamic.yaml", registry=plugins.registry)
    text = "\n".join(header(scenario, run_info(scenario, plugins=plugins), 0))
    assert "**Arm `told` was told what only the simulator knows**" in text
    assert "`moving_obstacles.cruise_speed_mm_s`" in text
    assert "Arm `moving` was told" not in text
    data = yaml.safe_load((repo / "scenarios" / "dynamic.yaml").read_text(encoding="utf-8"))
    del data["arms"]["told"]["told"]
    path = tmp_path / "undeclared.yaml"
    path.write_text(yaml.safe_dump(data), encoding="utf-8")
    undeclared = load_scenario(path, registry=plugins.registry)
    text = "\n".join(header(undeclared, run_info(undeclared, plugins=plugins), 0))
    assert "**Arm `told` was told what only the simulator knows**" in text
    assert "does not declare it (`told: true`)" in text
