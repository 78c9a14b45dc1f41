"""The previous release's module paths (``safeembodai_core.moved_modules``): each still imports, warns and
gives the module at its new path; the project's own code imports none of them."""

from __future__ import annotations

import ast
import importlib
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest
from import_statements import imported_from

from safeembodai_core.moved_modules import MOVED

REPO = Path(__file__).resolve().parents[2]
OWN_CODE = ("safeembodai_core", "plugins", "tests", "bench", "docs/examples")


@pytest.mark.parametrize("old", sorted(MOVED))
def test_an_old_path_warns_and_gives_the_module_at_its_new_path(old):
    """In a fresh interpreter (this one may have imported the old path already): the same object, so a
    class defined there is the same class, and the warning names the new path."""
    code = textwrap.dedent(f"""
        import importlib, warnings
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            old = importlib.import_module({old!r})
        new = importlib.import_module({MOVED[old]!r})
        assert old is new, (old, new)
        assert new.__name__ == {MOVED[old]!r} and new.__spec__.name == {MOVED[old]!r}
        messages = [str(w.message) for w in caught if issubclass(w.category, DeprecationWarning)]
        assert any({MOVED[old]!r} in m for m in messages), messages
    """)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO)
    assert done.returncode == 0, done.stderr


def test_a_plugin_importing_an_old_path_still_gets_the_same_classes():
    with pytest.warns(DeprecationWarning, match="safeembodai_core.contracts.components"):
        sys.modules.pop("safeembodai_core.components", None)
        old = importlib.import_module("safeembodai_core.components")
    from safeembodai_core import Environment
    assert old.Environment is Environment


def test_no_old_path_is_a_module_again():
    """A module of an old path would shadow nothing (the finder is last) but would split the code in two."""
    for old in MOVED:
        path = REPO / (old.replace(".", "/") + ".py")
        assert not path.exists(), f"{path} is back: update moved_modules.MOVED or move it"


def _imported_names(path: Path) -> list[tuple[int, str]]:
    rel = path.relative_to(REPO)
    module = ".".join(rel.with_suffix("").parts)
    is_package = rel.name == "__init__.py"
    found = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = imported_from(node, module, is_package)
            found += [(node.lineno, f"{base}.{alias.name}") for alias in node.names]
            found.append((node.lineno, base))
    return found


def test_the_projects_own_code_imports_no_old_path():
    users = []
    for folder in OWN_CODE:
        for path in sorted((REPO / folder).rglob("*.py")):
            if "build" in path.parts or path.name == "test_moved_modules.py":
                continue
            for line, name in _imported_names(path):
                hit = next((old for old in MOVED if name == old or name.startswith(old + ".")), None)
                if hit:
                    users.append(f"{path.relative_to(REPO)}:{line} imports {hit} (now {MOVED[hit]})")
    assert not users, "\n".join(users)
