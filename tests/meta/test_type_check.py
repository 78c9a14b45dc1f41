"""The code type-checks: ``mypy safeembodai_core`` and ``mypy plugins`` (the built-in plugins, with
the core modules they import) find no error, with the configuration of ``[tool.mypy]`` in
pyproject.toml (pydantic's plugin, unused ``type: ignore`` comments reported).

The integrations are checked against the libraries' own types, so the extras they import must be
installed (CI installs them all); without one both tests are skipped, naming it.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path

import pytest

pytest.importorskip("mypy", reason='needs the dev extra: pip install -e ".[dev]"')

#: The extras whose libraries the core imports, by the module it imports.
EXTRAS = {"gymnasium": "gym", "inspect_ai": "inspect", "ray": "ray"}


def _mypy(repo: Path, target: str) -> None:
    """Run ``mypy target`` from the repository root; fail with its output unless it finds no error."""
    missing = [f"{extra} ({module})" for module, extra in EXTRAS.items() if importlib.util.find_spec(module) is None]
    if missing:
        pytest.skip(f"mypy needs the types of the extras the core imports; not installed: {', '.join(missing)}")
    run = subprocess.run([sys.executable, "-m", "mypy", target], cwd=repo, capture_output=True,
                         text=True, timeout=600)
    assert run.returncode == 0, f"mypy {target} exited {run.returncode}:\n{run.stdout}{run.stderr}"


@pytest.mark.slow
@pytest.mark.timeout(660)  # _mypy's limit of 600 s, not the suite's default
def test_mypy_finds_no_error_in_the_core(repo):
    _mypy(repo, "safeembodai_core")


@pytest.mark.slow
@pytest.mark.timeout(660)  # _mypy's limit of 600 s, not the suite's default
def test_mypy_finds_no_error_in_the_plugins(repo):
    _mypy(repo, "plugins")
