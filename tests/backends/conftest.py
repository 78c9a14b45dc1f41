"""Fixtures for the backend tests: the fake OpenAI-compatible server and prompts built for real."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

from fake_openai import FakeOpenAI  # noqa: E402

FAKE_KEY = "sk-fake-0123456789abcdefXYZ"


@pytest.fixture
def fake_server():
    with FakeOpenAI() as server:
        yield server


@pytest.fixture
def fake_key(monkeypatch) -> str:
    monkeypatch.setenv("SAFEEMBODAI_TEST_KEY", FAKE_KEY)
    return FAKE_KEY


@pytest.fixture(scope="session")
def built_plugins():
    from safeembodai_core.plugins import load_plugins

    return load_plugins(environ={})
