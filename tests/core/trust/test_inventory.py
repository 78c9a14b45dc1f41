"""The inventory of ways in (``safeembodai_core/trust/inventory.py``) stays true: a module of the core or the
built-in plugins that calls a raw reader is listed there with its reason, no listed module is stale,
and every entry point's reader exists. A new reader of outside bytes fails here until it is listed."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

from safeembodai_core.trust.inventory import ENTRY_POINTS, RAW_READERS

REPO = Path(__file__).resolve().parents[3]
ROOTS = {"safeembodai_core": "safeembodai_core", "plugins": "safeembodai_plugins"}
#: attribute calls that read (or open) bytes, with the name they must be called on (None: any object)
RAW_ATTRIBUTES = {"read_text": None, "read_bytes": None, "open": None, "fdopen": "os", "loads": "json",
                  "load": "json", "model_validate_json": None, "safe_load": "yaml", "connect": "sqlite3"}


def raw_reads(tree: ast.AST) -> list[int]:
    """Lines of the raw reader calls in ``tree``."""
    lines = []
    for node in ast.walk(tree):
        if not isinstance(node, ast.Call):
            continue
        func = node.func
        if isinstance(func, ast.Name) and func.id == "open":
            lines.append(node.lineno)
        elif isinstance(func, ast.Attribute) and func.attr in RAW_ATTRIBUTES:
            owner = RAW_ATTRIBUTES[func.attr]
            if owner is None or (isinstance(func.value, ast.Name) and func.value.id == owner):
                lines.append(node.lineno)
    return lines


def modules_reading() -> dict[str, list[int]]:
    found = {}
    for folder, package in ROOTS.items():
        for path in sorted((REPO / folder).rglob("*.py")):
            parts = [package, *path.relative_to(REPO / folder).with_suffix("").parts]
            name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
            lines = raw_reads(ast.parse(path.read_text(encoding="utf-8")))
            if lines:
                found[name] = lines
    return found


def test_every_raw_reader_is_in_the_inventory_with_its_reason():
    unlisted = {name: lines for name, lines in modules_reading().items() if name not in RAW_READERS}
    assert not unlisted, (f"modules that read outside bytes without a strict reader: {unlisted}; read through an "
                          "entry point's reader (safeembodai_core/trust/inventory.py), or list the module there "
                          "with why")


def test_the_inventory_names_no_module_that_reads_nothing():
    stale = sorted(set(RAW_READERS) - set(modules_reading()))
    assert not stale, f"listed in RAW_READERS but reading nothing raw: {stale}"


#: the package each optional extra brings, as an entry's reader module imports it
EXTRA_PACKAGES = {"inspect": "inspect_ai", "ray": "ray", "gym": "gymnasium", "rerun": "rerun", "mcp": "mcp"}


def defined_in_source(module: str, qualified: str) -> bool:
    """Whether ``module``'s source defines ``qualified`` (``function`` or ``Class.method``), read without
    importing it: the reader of an extra that is not installed still has to exist."""
    package, *rest = module.split(".")
    folder = REPO / {package: folder for folder, package in ROOTS.items()}[package]
    path = folder.joinpath(*rest).with_suffix(".py")
    if not path.is_file():
        path = folder.joinpath(*rest, "__init__.py")
    scope: list[ast.stmt] = ast.parse(path.read_text(encoding="utf-8")).body
    for part in qualified.split("."):
        found = [node for node in scope if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef))
                 and node.name == part]
        if not found:
            return False
        scope = found[0].body
    return True


def test_every_entry_points_reader_exists():
    for entry in ENTRY_POINTS:
        module, _, qualified = entry.reader.partition(":")
        try:
            target = importlib.import_module(module)
        except ModuleNotFoundError as error:  # only an extra the entry names may be missing, and only here
            assert entry.extra and (error.name or "").split(".")[0] == EXTRA_PACKAGES[entry.extra], (entry, error)
            assert defined_in_source(module, qualified), entry
            continue
        for part in qualified.split("."):
            target = getattr(target, part)
        assert callable(target), entry


def test_the_source_check_finds_readers_and_misses():
    assert defined_in_source("safeembodai_core.integrations.inspect.bridge", "backend_reply")
    assert defined_in_source("safeembodai_plugins.state.sqlite_db", "SqliteStateStore._row")
    assert not defined_in_source("safeembodai_core.integrations.inspect.bridge", "no_such_reader")
    assert not defined_in_source("safeembodai_plugins.state.sqlite_db", "SqliteStateStore.no_such_method")


def test_the_check_sees_a_new_reader():
    assert raw_reads(ast.parse("import json\njson.loads(x)\nopen('f')\nPath('x').read_text()\n")) == [2, 3, 4]
    assert raw_reads(ast.parse("import orjson\norjson.loads(x)\n")) == []  # a miss the list would need to learn
