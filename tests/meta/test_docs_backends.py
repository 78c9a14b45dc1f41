"""docs/backends.md: every option of every backend and perception documented, every YAML example valid."""

from __future__ import annotations

import re

import pytest
import yaml

from safeembodai_core.scenario import parse_scenario

COMPONENTS = [("llm_backend", "gpt-4o"), ("llm_backend", "litellm"), ("llm_backend", "local"),
              ("llm_backend", "mock"), ("perception", "images"), ("perception", "text")]


@pytest.fixture(scope="module")
def text(repo_root):
    return (repo_root / "docs" / "backends.md").read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def repo_root():
    from pathlib import Path

    return Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("kind,name", COMPONENTS)
def test_every_option_is_documented(built_plugins, text, kind, name):
    assert f"`{name}`" in text
    for option in built_plugins.registry.get(kind, name).options.model_fields:
        assert f"`{option}`" in text, f"{name}.{option} is not documented in docs/backends.md"


def test_yaml_examples_are_valid_scenario_parts(built_plugins, text):
    blocks = re.findall(r"```yaml\n(.*?)```", text, re.S)
    assert len(blocks) >= 6
    for block in blocks:
        scenario = {"name": "docs", "environments": ["flatland"], **yaml.safe_load(block)}
        parse_scenario(yaml.safe_dump(scenario), "docs/backends.md", registry=built_plugins.registry)


def test_the_calibration_table_is_filled_in(text):
    assert "CALIBRATION_TABLE" not in text
    assert "simulate an LLM; they do not measure one" in text
