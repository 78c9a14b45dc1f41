"""Packaging hygiene: every package folder is listed in pyproject.toml, templates ship as data."""

from __future__ import annotations

import tomllib

ROOTS = {"safeembodai_core": "safeembodai_core", "plugins": "safeembodai_plugins", "prompts": "safeembodai_prompts"}


def test_every_package_folder_is_listed(repo):
    listed = set(tomllib.loads((repo / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = set()
    for folder, name in ROOTS.items():
        for init in (repo / folder).rglob("__init__.py"):
            relative = init.parent.relative_to(repo / folder)
            found.add(".".join((name, *relative.parts)))
    assert found == listed, f"missing from pyproject: {sorted(found - listed)}; stale: {sorted(listed - found)}"


def test_prompt_templates_are_package_data(repo):
    data = tomllib.loads((repo / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "*.j2" in data["safeembodai_prompts"] and "**/*.j2" in data["safeembodai_prompts"]
