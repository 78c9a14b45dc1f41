"""The Python examples in the docs run as written."""

from __future__ import annotations

import re

import pytest

DOCS = ["library.md"]


def code_blocks(path):
    return re.findall(r"```python\n(.*?)```", path.read_text(), re.S)


@pytest.mark.parametrize("doc", DOCS)
def test_python_examples_run(doc, repo, capsys):
    blocks = code_blocks(repo / "docs" / doc)
    assert blocks, f"{doc} has no python example"
    for block in blocks:
        exec(compile(block, f"docs/{doc}", "exec"), {"__name__": "docs_example"})
    out = capsys.readouterr().out
    if doc == "library.md":
        assert "lidar_clearance: straight forward 390 mm" in out
        assert "completed" in out and "refused by lidar_clearance" in out


def test_plugin_authors_test_example_passes(repo, monkeypatch):
    monkeypatch.syspath_prepend(str(repo / "docs" / "examples" / "safeembodai-example-plugin"))
    block = code_blocks(repo / "docs" / "plugins.md")[-1]
    namespace: dict = {"__name__": "docs_plugins_example"}
    exec(compile(block, "docs/plugins.md", "exec"), namespace)
    namespace["test_slow_zone_refuses_long_moves_near_obstacles"]()
