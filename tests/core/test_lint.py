"""Undefined names, unused imports and syntax errors fail the suite (ruff's F and E9 rules)."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest


def test_code_has_no_undefined_names_or_unused_imports(repo):
    beside_python = Path(sys.executable).parent / "ruff"  # the venv's own, even if its bin is not on PATH
    ruff = str(beside_python) if beside_python.exists() else shutil.which("ruff")
    if ruff is None:
        pytest.skip('ruff is not installed (it comes with pip install -e ".[dev]")')
    folders = ["safeembodai_core", "plugins", "prompts", "tests", "bench", "docs/examples"]
    completed = subprocess.run([ruff, "check", "--select", "F,E9", "--output-format", "concise", *folders],
                               cwd=repo, capture_output=True, text=True)
    assert completed.returncode == 0, completed.stdout + completed.stderr
