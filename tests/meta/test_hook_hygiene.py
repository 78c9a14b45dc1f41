"""Meta-tests: every hook spec is documented in docs/plugin_hooks.md and exercised by a test."""

from __future__ import annotations

import inspect
import re

import pytest

from safeembodai_core import hookspecs

HOOKS = sorted(name for name, value in vars(hookspecs).items()
               if inspect.isfunction(value) and hasattr(value, "safeembodai_spec"))


def test_hookspecs_are_found():
    assert {"register_validators", "register_commands", "after_step"} <= set(HOOKS)


@pytest.mark.parametrize("hook", HOOKS)
def test_every_hook_has_a_docstring(hook):
    assert (getattr(hookspecs, hook).__doc__ or "").strip()


@pytest.mark.parametrize("hook", HOOKS)
def test_every_hook_has_a_documented_heading(hook, repo):
    text = (repo / "docs" / "plugin_hooks.md").read_text()
    assert re.search(rf"^## {hook}$", text, re.M), f"docs/plugin_hooks.md has no '## {hook}' heading"


@pytest.mark.parametrize("hook", HOOKS)
def test_every_hook_is_exercised_by_a_test(hook, repo):
    me = __file__
    sources = [p for p in (repo / "tests").rglob("test_*.py") if str(p) != me]
    assert any(re.search(rf"\b{hook}\b", p.read_text()) for p in sources), f"no test mentions hook {hook}"


def test_documented_headings_are_all_real_hooks(repo):
    text = (repo / "docs" / "plugin_hooks.md").read_text()
    assert sorted(re.findall(r"^## (\w+)$", text, re.M)) == HOOKS
