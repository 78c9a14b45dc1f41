"""Every Python example in README.md and docs/ runs as written: each block on its own (a reader may
copy any one of them), a page's blocks in order, in a scratch folder."""

from __future__ import annotations

import re
import textwrap
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PAGES = sorted(str(p.relative_to(REPO)) for p in [REPO / "README.md", *(REPO / "docs").rglob("*.md")]
               if "```python" in p.read_text(encoding="utf-8"))
#: what a page's examples need beyond the dev install (the extra is installed in CI)
NEEDS = {"docs/gymnasium.md": "gymnasium", "docs/inspect.md": "inspect_ai"}


def code_blocks(path):
    """The page's ``python`` blocks, dedented (a block inside a list item is indented)."""
    return [textwrap.dedent(block) for block in re.findall(r"```python\n(.*?)```", path.read_text(), re.S)]


@pytest.fixture
def example_plugin_installed(repo, monkeypatch):
    """As if ``pip install ./docs/examples/safeembodai-example-plugin`` had run: found by every load."""
    monkeypatch.syspath_prepend(str(repo / "docs" / "examples" / "safeembodai-example-plugin"))
    import safeembodai_example

    from safeembodai_core.guard import guard as api
    from safeembodai_core.plugin import manager as plugins

    def load_plugins(extra=(), **kwargs):
        loaded = plugins.load_plugins(extra, **kwargs)
        if loaded.pm.get_plugin("example") is None:  # not installed in this environment
            loaded = plugins.load_plugins([*extra, ("example", safeembodai_example)], **kwargs)
        return loaded

    monkeypatch.setattr(api, "load_plugins", load_plugins)


def test_every_page_with_examples_is_found():
    assert {"README.md", "docs/library.md", "docs/robots.md", "docs/plugins.md"} <= set(PAGES)


@pytest.mark.parametrize("doc", PAGES)
def test_python_examples_run(doc, repo, capsys, example_plugin_installed, tmp_path, monkeypatch):
    if doc in NEEDS:
        pytest.importorskip(NEEDS[doc], reason=f"{doc}'s examples need the {NEEDS[doc]} extra")
    monkeypatch.chdir(tmp_path)
    if doc == "docs/inspect.md":  # its example reads the log of an `inspect eval` run before it
        from inspect_ai import eval as inspect_eval

        inspect_eval("safeembodai/mo", model="safeembodai/mock", task_args={"trials": 1}, log_dir="logs",
                     display="none")
    blocks = code_blocks(repo / doc)
    assert blocks, f"{doc} has no python example"
    for block in blocks:
        exec(compile(block, doc, "exec"), {"__name__": "docs_example"})  # self-contained: a fresh namespace
    out = capsys.readouterr().out
    if doc == "README.md":
        assert out.startswith("False ['swept_body (signal 1): straight forward 350 mm")  # the robot defaults
        assert "at most 229 mm is safe" in out  # the 170 mm disc meets the return 400 mm ahead after 230 mm
    if doc == "docs/library.md":
        assert "lidar_clearance (signal 1): straight forward 390 mm" in out
        assert "completed" in out and "refused by lidar_clearance" in out
        assert ("geofence (signal 2): straight forward 390 mm leaves the robot's area: "
                "at most 183 mm forward is safe" in out)


def test_plugin_authors_test_example_passes(repo, monkeypatch):
    monkeypatch.syspath_prepend(str(repo / "docs" / "examples" / "safeembodai-example-plugin"))
    block = code_blocks(repo / "docs" / "plugins.md")[-1]
    namespace: dict = {"__name__": "docs_plugins_example"}
    exec(compile(block, "docs/plugins.md", "exec"), namespace)
    tests = [name for name in namespace if name.startswith("test_")]
    assert {"test_slow_zone_refuses_long_moves_near_obstacles",
            "test_geofence_refuses_a_plan_that_leaves_the_rectangle"} <= set(tests)
    for name in tests:
        namespace[name]()
