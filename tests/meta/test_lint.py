"""The lint rules pyproject.toml selects ([tool.ruff.lint]) fail the suite: undefined names, unused
imports, syntax errors, misplaced imports, lines over 120 columns, needless statements and returns."""

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
    folders = ["safeembodai_core", "plugins", "prompts", "tests", "bench", "docs/examples", "safeembodai.py"]
    completed = subprocess.run([ruff, "check", "--output-format", "concise", *folders],
                               cwd=repo, capture_output=True, text=True)
    assert completed.returncode == 0, completed.stdout + completed.stderr
