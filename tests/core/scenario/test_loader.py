"""Scenario errors name the file, line and key; --set overrides are validated like the file."""

from __future__ import annotations

import pytest

from safeembodai_core.errors import ScenarioError
from safeembodai_core.runs.runner import ScenarioRunner, trial_seed
from safeembodai_core.scenario import load_scenario, parse_scenario

GOOD = """\
name: demo
seed: 7
trials: 3
environments:
  - use: flatland
    options: {obstacles: 2}
backend:
  use: scripted
  options:
    responses: ['{"perception": [], "planning": "p", "control": [{"command": "turn", "direction": "left", \
"angle": 30}]}']
arms:
  baseline: {}
  safeembodai: {security_prefix: true, state_management: true, safety_validation: true}
conditions:
  no_attack: {}
  attack:
    attackers: [{use: prompt_injection, options: {rate: 0.5}}]
"""


def test_good_scenario_loads_and_pairs_seeds(tmp_path, plugins):
    path = tmp_path / "demo.yaml"
    path.write_text(GOOD)
    scenario = load_scenario(path, registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    specs = runner.specs()
    assert len(specs) == 1 * 2 * 2 * 3
    by_index = {}
    for spec in specs:
        by_index.setdefault((spec.environment, spec.index), set()).add(spec.seed)
    assert all(len(seeds) == 1 for seeds in by_index.values())  # every arm and condition faces the same worlds
    env = scenario.environments[0].key
    assert (by_index[(env, 0)] == {trial_seed(scenario, env, 0)}
            and trial_seed(scenario, env, 0) != trial_seed(scenario, env, 1))


def test_type_errors_name_file_line_and_key():
    text = GOOD.replace("trials: 3", "trials: many")
    with pytest.raises(ScenarioError) as error:
        parse_scenario(text, "demo.yaml")
    assert "demo.yaml:3: trials:" in str(error.value)


def test_unknown_keys_are_named_with_their_line():
    text = GOOD.replace("  baseline: {}", "  baseline: {security_prefx: true}")
    with pytest.raises(ScenarioError, match=r"demo.yaml:12: arms.baseline.security_prefx: Extra inputs"):
        parse_scenario(text, "demo.yaml")


def test_unknown_component_is_named_with_its_line(plugins):
    text = GOOD.replace("use: prompt_injection", "use: prompt_injektion")
    with pytest.raises(ScenarioError) as error:
        parse_scenario(text, "demo.yaml", registry=plugins.registry)
    message = str(error.value)
    assert "demo.yaml:17" in message and "conditions.attack.attackers.0" in message
    assert "Did you mean 'prompt_injection'" in message


def test_bad_component_options_name_the_key_and_the_plugin(plugins):
    text = GOOD.replace("options: {rate: 0.5}", "options: {rate: 5, colour: red}")
    with pytest.raises(ScenarioError) as error:
        parse_scenario(text, "demo.yaml", registry=plugins.registry)
    message = str(error.value)
    assert "conditions.attack.attackers.0.options.rate" in message
    assert "conditions.attack.attackers.0.options.colour" in message
    assert "from plugin 'attackers'" in message and "demo.yaml:17" in message


def test_overrides_apply_and_are_validated_like_the_file(plugins):
    scenario = parse_scenario(GOOD, "demo.yaml", ["arms.safeembodai.failure_threshold=5", "seed=9"], plugins.registry)
    assert scenario.arms["safeembodai"].failure_threshold == 5 and scenario.seed == 9
    with pytest.raises(ScenarioError, match=r"--set arms.safeembodai.failure_threshold: .*greater than or equal to 0"):
        parse_scenario(GOOD, "demo.yaml", ["arms.safeembodai.failure_threshold=-2"])
    with pytest.raises(ScenarioError, match="expected dotted.key=value"):
        parse_scenario(GOOD, "demo.yaml", ["seed"])
    scenario = parse_scenario(GOOD, "demo.yaml", ["environments.0.options.obstacles=4"], plugins.registry)
    assert scenario.environments[0].options == {"obstacles": 4}


def test_a_component_named_alone_takes_options_from_the_command_line(plugins):
    """``backend: mock`` (a name, not a mapping) and a perception the scenario never names still take
    ``--set KEY.options.X=...``: the name becomes ``{use: name}``, a missing one its default's name."""
    text = "name: demo\nenvironments: [flatland]\nbackend: mock\n"
    scenario = parse_scenario(text, "demo.yaml",
                              ["backend.options.ignore_clearance_p=0.5", "perception.options.lidar_image_px=120",
                               "environments.0.label=room"], plugins.registry)
    assert (scenario.backend.use, scenario.backend.options) == ("mock", {"ignore_clearance_p": 0.5})
    assert scenario.perception.use == "images" and scenario.perception.options == {"lidar_image_px": 120}
    assert scenario.environments[0].key == "room"
    with pytest.raises(ScenarioError, match=r"backend.options.nope: .*Extra inputs are not permitted"):
        parse_scenario(text, "demo.yaml", ["backend.options.nope=1"], plugins.registry)


def test_repeated_keys_and_broken_yaml_are_errors():
    with pytest.raises(ScenarioError, match="demo.yaml:4: seed: key repeated"):
        parse_scenario(GOOD.replace("trials: 3", "trials: 3\nseed: 8"), "demo.yaml")
    with pytest.raises(ScenarioError, match="demo.yaml:2: not valid YAML"):
        parse_scenario("name: x\n  bad: [", "demo.yaml")
    with pytest.raises(ScenarioError, match="must be a YAML mapping"):
        parse_scenario("- a\n- b\n", "demo.yaml")


def test_missing_file_is_named(tmp_path):
    with pytest.raises(ScenarioError, match="nowhere.yaml: no such scenario file"):
        load_scenario(tmp_path / "nowhere.yaml")


def test_shipped_scenarios_are_valid(repo, plugins):
    paths = sorted((repo / "scenarios").glob("*.yaml"))
    assert paths, "scenarios/ ships no scenario"
    for path in paths:
        load_scenario(path, registry=plugins.registry)


def test_unknown_security_prefix_variant_is_caught_at_load(plugins):
    text = GOOD.replace("safeembodai: {security_prefix: true,", "safeembodai: {security_prefix: stricter,")
    with pytest.raises(ScenarioError) as error:
        parse_scenario(text, "demo.yaml", registry=plugins.registry)
    message = str(error.value)
    assert "demo.yaml:13: arms.safeembodai.security_prefix" in message and "'stricter'" in message
    assert "paper" in message and "spotlight" in message
    ok = parse_scenario(GOOD.replace("security_prefix: true", "security_prefix: spotlight"), "demo.yaml",
                        registry=plugins.registry)
    assert ok.arms["safeembodai"].prefix_variant == "spotlight"
