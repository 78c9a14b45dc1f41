"""Shared fixtures. Tests never need network access, an API key or a display."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
os.environ.setdefault("LITELLM_LOCAL_MODEL_COST_MAP", "True")


@pytest.fixture(scope="session")
def repo() -> Path:
    return REPO


@pytest.fixture
def plugins():
    """A fresh plugin set (built-ins and installed entry points), isolated per test."""
    from safeembodai_core.plugins import load_plugins

    return load_plugins(environ={})


@pytest.fixture
def cli_runner():
    from click.testing import CliRunner

    return CliRunner()


@pytest.fixture
def python() -> str:
    return sys.executable
