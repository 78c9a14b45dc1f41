"""The Python examples in the docs run as written."""

from __future__ import annotations

import re

import pytest

DOCS = ["library.md"]


def code_blocks(path):
    return re.findall(r"```python\n(.*?)```", path.read_text(), re.S)


@pytest.fixture
def example_plugin_installed(repo, monkeypatch):
    """As if ``pip install ./docs/examples/safeembodai-example-plugin`` had run: found by every load."""
    monkeypatch.syspath_prepend(str(repo / "docs" / "examples" / "safeembodai-example-plugin"))
    import safeembodai_example

    from safeembodai_core import api, plugins

    def load_plugins(extra=(), **kwargs):
        loaded = plugins.load_plugins(extra, **kwargs)
        if loaded.pm.get_plugin("example") is None:  # not installed in this environment
            loaded = plugins.load_plugins([*extra, ("example", safeembodai_example)], **kwargs)
        return loaded

    monkeypatch.setattr(api, "load_plugins", load_plugins)


@pytest.mark.parametrize("doc", DOCS)
def test_python_examples_run(doc, repo, capsys, example_plugin_installed):
    blocks = code_blocks(repo / "docs" / doc)
    assert blocks, f"{doc} has no python example"
    for block in blocks:
        exec(compile(block, f"docs/{doc}", "exec"), {"__name__": "docs_example"})
    out = capsys.readouterr().out
    if doc == "library.md":
        assert "lidar_clearance (signal 1): straight forward 390 mm" in out
        assert "completed" in out and "refused by lidar_clearance" in out
        assert "geofence (signal 2): straight forward 390 mm leaves the robot's area: at most 183 mm forward is safe" in out


def test_plugin_authors_test_example_passes(repo, monkeypatch):
    monkeypatch.syspath_prepend(str(repo / "docs" / "examples" / "safeembodai-example-plugin"))
    block = code_blocks(repo / "docs" / "plugins.md")[-1]
    namespace: dict = {"__name__": "docs_plugins_example"}
    exec(compile(block, "docs/plugins.md", "exec"), namespace)
    tests = [name for name in namespace if name.startswith("test_")]
    assert {"test_slow_zone_refuses_long_moves_near_obstacles", "test_geofence_refuses_a_plan_that_leaves_the_rectangle"} <= set(tests)
    for name in tests:
        namespace[name]()
