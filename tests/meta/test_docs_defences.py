"""docs/defences.md and docs/attacks.md: every built-in option documented, every YAML example valid."""

from __future__ import annotations

import re
import shutil

import pytest
import yaml

from safeembodai_core.scenario import parse_scenario
from safeembodai_plugins.attackers.library import PAYLOADS
from safeembodai_plugins.attackers.poisoning import KINDS

COMPONENTS = {
    "defences.md": [("prompt_builder", "jinja"), ("state_store", "memory"), ("state_store", "sqlite"),
                    ("validator", "command_limits"), ("validator", "lidar_clearance"),
                    ("validator", "footprint_sweep"), ("validator", "moving_obstacles")],
    "attacks.md": [("attacker", "prompt_injection"), ("attacker", "lidar_spoof"), ("attacker", "state_poisoning")],
}


def doc(repo, name: str) -> str:
    return (repo / "docs" / name).read_text(encoding="utf-8")


@pytest.mark.parametrize("name", sorted(COMPONENTS))
def test_every_option_of_every_builtin_is_documented(plugins, repo, name):
    text = doc(repo, name)
    for kind, component in COMPONENTS[name]:
        assert f"`{component}`" in text, component
        for option in plugins.registry.get(kind, component).options.model_fields:
            assert f"`{option}`" in text, f"{component}.{option} is not documented in {name}"


def test_every_payload_kind_variant_and_forgery_is_documented(repo, plugins):
    attacks, defences = doc(repo, "attacks.md"), doc(repo, "defences.md")
    for kind in [*PAYLOADS, *KINDS]:
        assert f"`{kind}`" in attacks, kind
    variants = plugins.registry.build("prompt_builder", "jinja", {}).templates.variants()
    for variant in variants:
        assert f"`{variant}`" in defences, variant


@pytest.mark.parametrize("name", sorted(COMPONENTS))
def test_yaml_examples_are_valid_scenario_parts(plugins, repo, name, tmp_path, monkeypatch):
    # the docs point template_dir at a user folder "my_prompts": give them one, as a user would
    shutil.copytree(repo / "prompts", tmp_path / "my_prompts")
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```yaml\n(.*?)```", doc(repo, name), re.S)
    assert len(blocks) >= 3
    for block in blocks:
        data = yaml.safe_load(block)
        scenario = {"name": "docs", "environments": ["flatland"], **data}
        if "conditions" in data and "arms" not in data:
            scenario["arms"] = {"arm": {"state_management": True}}
        parse_scenario(yaml.safe_dump(scenario), f"docs/{name}", registry=plugins.registry)
