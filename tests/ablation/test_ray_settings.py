"""How the ray executor starts Ray, checked without Ray installed (a stand-in module)."""

from __future__ import annotations

import os
import sys
from types import SimpleNamespace

from safeembodai_core.ablation.executors import RayExecutor


def fake_ray(seen: dict) -> SimpleNamespace:
    def init(**kwargs):
        seen["usage_stats"] = os.environ.get("RAY_USAGE_STATS_ENABLED")
        seen["kwargs"] = kwargs

    def options(**kwargs):
        seen["actor_options"] = kwargs
        return SimpleNamespace(remote=lambda *args: object())

    return SimpleNamespace(is_initialized=lambda: False, init=init,
                           remote=lambda cls: SimpleNamespace(options=options))


def test_a_run_never_phones_home_unless_the_user_says_so(monkeypatch):
    seen: dict = {}
    monkeypatch.setitem(sys.modules, "ray", fake_ray(seen))
    monkeypatch.delenv("RAY_USAGE_STATS_ENABLED", raising=False)
    RayExecutor({}, "/nonexistent", workers=1, address=None)
    assert seen["usage_stats"] == "0"
    assert seen["kwargs"]["include_dashboard"] is False and seen["kwargs"]["_node_ip_address"] == "127.0.0.1"
    assert seen["actor_options"] == {"max_concurrency": 1}
    RayExecutor({}, "/nonexistent", workers=1, address=None, concurrency=16)
    assert seen["actor_options"] == {"max_concurrency": 16}  # a threaded actor: 16 trials in flight each
    monkeypatch.setenv("RAY_USAGE_STATS_ENABLED", "1")  # turned on by the user: left on
    RayExecutor({}, "/nonexistent", workers=1, address=None)
    assert seen["usage_stats"] == "1"
