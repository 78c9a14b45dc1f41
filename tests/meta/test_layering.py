"""Layering: the core knows no plugin's insides, plugins do not import the CLI, and no two modules
import each other (issue 25).

The import graph is read from the source with ``ast``: every ``import`` and ``from ... import``
statement, at module level, inside functions and under ``TYPE_CHECKING`` alike, between the
modules of ``safeembodai_core`` and of the built-in plugins (``plugins/``, imported as
``safeembodai_plugins``). A function-level import that only defers a heavy library is fine; one
that exists to dodge a cycle is a cycle all the same, and fails here. What importing a submodule
runs implicitly (its packages' ``__init__``) is not an edge.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from import_statements import imported_from

REPO = Path(__file__).resolve().parents[2]
ROOTS = {"safeembodai_core": "safeembodai_core", "plugins": "safeembodai_plugins"}

#: Module prefixes left out of the cycle checks for now (the backends are being reorganised);
#: empty this to hold them to the same rule.
CYCLE_CHECK_EXCLUDES: tuple[str, ...] = ()  # modules left out of the cycle checks (none)

#: What only the ``sqlite`` plugin may know: its file name and SQL over its tables.
STORE_TABLES = ("steps", "verdicts", "attacks", "attempts", "trials", "meta")
SQL_ON_STORE_TABLES = re.compile(rf"\b(?:FROM|INTO|UPDATE|JOIN|TABLE)\s+(?:{'|'.join(STORE_TABLES)})\b")


def _modules() -> dict[str, tuple[Path, bool]]:
    """Module name -> (file, is a package's ``__init__``)."""
    found = {}
    for folder, package in ROOTS.items():
        for path in sorted((REPO / folder).rglob("*.py")):
            parts = [package, *path.relative_to(REPO / folder).with_suffix("").parts]
            is_package = parts[-1] == "__init__"
            found[".".join(parts[:-1] if is_package else parts)] = (path, is_package)
    return found


MODULES = _modules()


def _imported(node: ast.AST, module: str, is_package: bool) -> list[str]:
    """The full names an import statement of ``module`` asks for (submodules where they are ones)."""
    if isinstance(node, ast.Import):
        return [alias.name for alias in node.names]
    if not isinstance(node, ast.ImportFrom):
        return []
    base = imported_from(node, module, is_package)
    return [f"{base}.{alias.name}" if f"{base}.{alias.name}" in MODULES else base for alias in node.names]


def _import_graph() -> dict[str, dict[str, int]]:
    """Module -> {module it imports: line of the first such import}, among :data:`MODULES`."""
    graph: dict[str, dict[str, int]] = {}
    for module, (path, is_package) in MODULES.items():
        edges = graph[module] = {}
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            for name in _imported(node, module, is_package):
                while name and name not in MODULES:  # a name imported from a module: that module
                    name = name.rpartition(".")[0]
                if name and name != module:
                    edges.setdefault(name, node.lineno)
    return graph


GRAPH = _import_graph()


def _checked(module: str) -> bool:
    return not any(module == prefix or module.startswith(prefix + ".") for prefix in CYCLE_CHECK_EXCLUDES)


def _cycles(graph: dict[str, dict[str, int]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan, iteratively)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found = []
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on_stack.add(root)
        while work:
            node, targets = work[-1]
            for target in targets:
                if target not in graph:
                    continue
                if target not in index:
                    index[target] = low[target] = len(index)
                    stack.append(target)
                    on_stack.add(target)
                    work.append((target, iter(sorted(graph[target]))))
                    break
                if target in on_stack:
                    low[node] = min(low[node], index[target])
            else:
                work.pop()
                if work:
                    low[work[-1][0]] = min(low[work[-1][0]], low[node])
                if low[node] == index[node]:
                    component = []
                    while True:
                        member = stack.pop()
                        on_stack.discard(member)
                        component.append(member)
                        if member == node:
                            break
                    if len(component) > 1:
                        found.append(sorted(component))
    return found


def _where(a: str, b: str) -> str:
    return f"{MODULES[a][0].relative_to(REPO)}:{GRAPH[a][b]}"


def test_the_graph_sees_imports_at_every_level():
    """Module level, relative, inside a function, under TYPE_CHECKING: all are edges."""
    assert "safeembodai_core.models" in GRAPH["safeembodai_core.runs.runner"]  # from .models import ...
    assert "safeembodai_core.ros.bag_export" in GRAPH["safeembodai_core.runs.artefacts"]  # inside a method
    assert "safeembodai_core.guard.guard" in GRAPH["safeembodai_core"]  # under TYPE_CHECKING
    assert "safeembodai_plugins.state.review" in GRAPH["safeembodai_plugins.state.sqlite_store"]  # inside a command
    assert "safeembodai_core.contracts.components" in GRAPH["safeembodai_plugins.state.memory_store"]  # plugin -> core


def test_the_cycle_finder_finds_cycles():
    graph = {"a": {"b": 1}, "b": {"c": 1}, "c": {"a": 1}, "d": {"a": 1}, "e": {"e": 1}}
    assert _cycles(graph) == [["a", "b", "c"]]
    assert _cycles({"a": {"b": 1}, "b": {}}) == []


def test_no_two_modules_import_each_other():
    pairs = [f"{a} ({_where(a, b)}) <-> {b} ({_where(b, a)})"
             for a in sorted(GRAPH) for b in sorted(GRAPH[a])
             if a < b and a in GRAPH.get(b, {}) and _checked(a) and _checked(b)]
    assert not pairs, "modules that import each other:\n" + "\n".join(pairs)


def test_no_longer_import_cycle_either():
    checked = {a: {b: line for b, line in edges.items() if _checked(b)} for a, edges in GRAPH.items() if _checked(a)}
    cycles = _cycles(checked)
    assert not cycles, "import cycles:\n" + "\n".join(
        " -> ".join(cycle) + "\n  " + ", ".join(f"{a} imports {b} at {_where(a, b)}" for a in cycle
                                                 for b in checked[a] if b in cycle) for cycle in cycles)


def test_the_core_imports_no_builtin_plugin():
    leaks = [f"{a} imports {b} ({_where(a, b)})" for a in GRAPH if a.split(".")[0] == "safeembodai_core"
             for b in GRAPH[a] if b.split(".")[0] == "safeembodai_plugins"]
    assert not leaks


def test_plugins_do_not_import_the_cli():
    """What a plugin shares with a command lives in the core (``trial_words``), not in the command."""
    leaks = [f"{a} imports {b} ({_where(a, b)})" for a in GRAPH if a.split(".")[0] == "safeembodai_plugins"
             for b in GRAPH[a] if b == "safeembodai_core.cli" or b.startswith("safeembodai_core.cli.")]
    assert not leaks


@pytest.mark.parametrize("path", sorted((REPO / "safeembodai_core").rglob("*.py")),
                         ids=lambda p: str(p.relative_to(REPO)))
def test_the_core_knows_nothing_of_the_sqlite_store(path):
    """The ``sqlite`` store's file and tables are the plugin's: the core asks ``StateStore.step_facts``."""
    text = path.read_text(encoding="utf-8")
    assert "results.sqlite" not in text
    assert not SQL_ON_STORE_TABLES.findall(text)
    tree = ast.parse(text)
    imports = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
    imports |= {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom) and not node.level}
    assert "sqlite3" not in imports


def test_the_store_queries_live_in_the_sqlite_plugin():
    """Where the report's counts are asked in SQL (and the scan above is not vacuous: it sees them)."""
    text = (REPO / "plugins" / "state" / "sqlite_db.py").read_text(encoding="utf-8")
    assert {"FROM verdicts", "FROM attacks", "FROM steps", "INTO steps"} <= set(SQL_ON_STORE_TABLES.findall(text))


#: the core's lowest packages: what a plugin's component and the Guard stand on
LOW_LAYERS = ("models", "contracts", "validation", "geometry", "trust")
#: what runs trials, reads scenarios or shows results: never imported by a low layer
HIGH_LAYERS = ("loop", "runs", "ablation", "cli", "report", "view", "guard", "scenario", "plugin")


def _under(module: str, package: str) -> bool:
    full = f"safeembodai_core.{package}"
    return module == full or module.startswith(full + ".")


def test_no_import_runs_from_a_low_layer_up():
    up = [f"{a} imports {b} ({_where(a, b)})" for a in GRAPH if any(_under(a, low) for low in LOW_LAYERS)
          for b in GRAPH[a] if any(_under(b, high) for high in HIGH_LAYERS)]
    assert not up, "\n".join(up)


def test_the_guard_knows_no_run_folder_loop_or_scenario():
    up = [f"{a} imports {b}" for a in GRAPH if _under(a, "guard") for b in GRAPH[a]
          if any(_under(b, high) for high in ("runs", "ablation", "report", "cli", "loop", "scenario", "view"))]
    assert not up, "\n".join(up)


def test_the_scenario_schema_knows_of_the_loop_only_its_defences_model():
    up = {b for a in GRAPH if _under(a, "scenario") for b in GRAPH[a] if _under(b, "loop")}
    assert up <= {"safeembodai_core.loop.defences"}, up
