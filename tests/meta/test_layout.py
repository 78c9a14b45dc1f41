"""Packaging hygiene: every package folder is listed in pyproject.toml, templates ship as data."""

from __future__ import annotations

import tomllib

ROOTS = {"safeembodai_core": "safeembodai_core", "plugins": "safeembodai_plugins", "prompts": "safeembodai_prompts"}


def test_every_package_folder_is_listed(repo):
    """Data-only folders count too: setuptools warns about (and will drop) one it is not told about."""
    listed = set(tomllib.loads((repo / "pyproject.toml").read_text())["tool"]["setuptools"]["packages"])
    found = set()
    for folder, name in ROOTS.items():
        for path in (repo / folder).rglob("*"):
            if path.is_file() and "__pycache__" not in path.parts and not path.name.startswith("."):
                relative = path.parent.relative_to(repo / folder)
                found.add(".".join((name, *relative.parts)))
    assert found == listed, f"missing from pyproject: {sorted(found - listed)}; stale: {sorted(listed - found)}"


def test_prompt_templates_are_package_data(repo):
    data = tomllib.loads((repo / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "*.j2" in data["safeembodai_prompts"] and "**/*.j2" in data["safeembodai_prompts"]


def test_gitignore_ignores_run_folders_and_inspect_logs(repo):
    """``safeembodai`` writes runs to ``runs/``, ``inspect eval`` its ``.eval`` logs to ``./logs``."""
    patterns = {line.strip() for line in (repo / ".gitignore").read_text().splitlines()}
    for folder in ("runs", "logs"):
        assert patterns & {f"{folder}/", f"/{folder}/", folder, f"/{folder}"}, f"{folder}/ is not in .gitignore"
