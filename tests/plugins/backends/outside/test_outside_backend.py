"""``outside``: the backend a serve-robot session records; it names the client as outside and answers nothing."""

from __future__ import annotations

import pytest

from safeembodai_core.errors import BackendError
from safeembodai_core.plugin.manager import load_plugins


def test_it_says_who_drove_and_never_answers_a_prompt():
    registry = load_plugins(environ={}).registry
    described = registry.get("llm_backend", "outside").options().describe()
    assert "outside client over rosbridge" in described.model and described.simulated is None
    backend = registry.build("llm_backend", "outside", {})
    with pytest.raises(BackendError, match="came from a client outside this process"):
        backend.complete(None, None)
