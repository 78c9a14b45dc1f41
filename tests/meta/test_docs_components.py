"""The reference pages of the built-in components: docs/backends.md, docs/defences.md and
docs/attacks.md document every option of every built-in they cover, and every YAML example on them
is a valid scenario part."""

from __future__ import annotations

import re
import shutil

import pytest
import yaml

from safeembodai_core.scenario import parse_scenario
from safeembodai_plugins.attackers.library import PAYLOADS
from safeembodai_plugins.attackers.poisoning import KINDS

COMPONENTS = {
    "backends.md": [("llm_backend", "gpt-4o"), ("llm_backend", "litellm"), ("llm_backend", "local"),
                    ("llm_backend", "mock"), ("perception", "images"), ("perception", "text")],
    "defences.md": [("prompt_builder", "jinja"), ("state_store", "memory"), ("state_store", "sqlite"),
                    ("validator", "command_limits"), ("validator", "lidar_clearance"),
                    ("validator", "footprint_sweep"), ("validator", "moving_obstacles")],
    "attacks.md": [("attacker", "prompt_injection"), ("attacker", "lidar_spoof"), ("attacker", "state_poisoning")],
}
#: the least number of YAML examples each page holds
MIN_EXAMPLES = {"backends.md": 6, "defences.md": 3, "attacks.md": 3}
#: pages whose examples may set conditions without arms (given one arm here, as a scenario would)
ARMS_ELSEWHERE = {"defences.md", "attacks.md"}


def doc(repo, name: str) -> str:
    return (repo / "docs" / name).read_text(encoding="utf-8")


@pytest.mark.parametrize("name,kind,component", [(name, kind, component) for name, built in COMPONENTS.items()
                                                 for kind, component in built])
def test_every_option_of_every_builtin_is_documented(built_plugins, repo, name, kind, component):
    text = doc(repo, name)
    assert f"`{component}`" in text, component
    for option in built_plugins.registry.get(kind, component).options.model_fields:
        assert f"`{option}`" in text, f"{component}.{option} is not documented in docs/{name}"


def test_every_payload_kind_variant_and_forgery_is_documented(repo, built_plugins):
    attacks, defences = doc(repo, "attacks.md"), doc(repo, "defences.md")
    for kind in [*PAYLOADS, *KINDS]:
        assert f"`{kind}`" in attacks, kind
    variants = built_plugins.registry.build("prompt_builder", "jinja", {}).templates.variants()
    for variant in variants:
        assert f"`{variant}`" in defences, variant


@pytest.mark.parametrize("name", sorted(COMPONENTS))
def test_yaml_examples_are_valid_scenario_parts(built_plugins, repo, name, tmp_path, monkeypatch):
    # the docs point template_dir at a user folder "my_prompts": give them one, as a user would
    shutil.copytree(repo / "prompts", tmp_path / "my_prompts")
    monkeypatch.chdir(tmp_path)
    blocks = re.findall(r"```yaml\n(.*?)```", doc(repo, name), re.S)
    assert len(blocks) >= MIN_EXAMPLES[name]
    for block in blocks:
        data = yaml.safe_load(block)
        scenario = {"name": "docs", "environments": ["flatland"], **data}
        if name in ARMS_ELSEWHERE and "conditions" in data and "arms" not in data:
            scenario["arms"] = {"arm": {"state_management": True}}
        parse_scenario(yaml.safe_dump(scenario), f"docs/{name}", registry=built_plugins.registry)


def test_the_calibration_table_is_filled_in(repo):
    text = doc(repo, "backends.md")
    assert "CALIBRATION_TABLE" not in text
    assert "simulate an LLM; they do not measure one" in text
