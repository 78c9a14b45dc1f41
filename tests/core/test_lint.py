"""Undefined names, unused imports and syntax errors fail the suite (ruff's F and E9 rules)."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest


def test_code_has_no_undefined_names_or_unused_imports(repo):
    ruff = shutil.which("ruff") or shutil.which("ruff", path=str(__import__("pathlib").Path(sys.executable).parent))
    if ruff is None:
        pytest.skip('ruff is not installed (it comes with pip install -e ".[dev]")')
    folders = ["safeembodai_core", "plugins", "prompts", "tests", "bench", "docs/examples"]
    completed = subprocess.run([ruff, "check", "--select", "F,E9", "--output-format", "concise", *folders],
                               cwd=repo, capture_output=True, text=True)
    assert completed.returncode == 0, completed.stdout + completed.stderr
