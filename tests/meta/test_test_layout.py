"""The tests mirror the source (tests/README.md): a test file lives in the folder of the package it
tests, its name and its tests' names say what they test (no history), and no module is tested by two
files of the same name.

The checks are functions of a list of paths, so the last test can show that the layout this one
replaced fails them.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path, PurePosixPath

REPO = Path(__file__).resolve().parents[2]

#: test folder -> the source folder it mirrors: tests/core/loop/ tests safeembodai_core/loop/, and so
#: on down; every folder under these must mirror a source package that exists.
MIRROR = {
    "tests/core": "safeembodai_core",
    "tests/plugins": "plugins",
    "tests/prompts": "prompts",
}
#: folders that mirror no source package: tests about the project itself, and helper modules
#: (on sys.path through pyproject's ``pythonpath``; no test files).
META, SUPPORT = "tests/meta", "tests/support"

#: Test files and folders still in the old layout (being edited elsewhere when the rest moved), and
#: where they go. Each must still exist: drop an entry when it has moved. Empty: every test is in place.
PENDING: dict[str, str] = {}

#: words that tell a test's history instead of what it checks
HISTORY = re.compile(r"(?:^|_)(?:issues?|pin|pins|pinned|pinning|regressions?|fix|fixes|bugfix|hotfix|bugs?|"
                     r"todo|xxx|old_behaviou?r)(?:_|$|\d)")


def all_test_files(root: Path = REPO) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in (root / "tests").rglob("test_*.py")
                  if "__pycache__" not in p.parts)


def helper_files(root: Path = REPO) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in (root / "tests").rglob("*.py")
                  if "__pycache__" not in p.parts and not p.name.startswith("test_")
                  and p.name not in ("conftest.py", "__init__.py"))


def pending(path: str) -> bool:
    return any(path == p or path.startswith(p + "/") for p in PENDING)


def mirrored(folder: str) -> str | None:
    """The source folder a test folder mirrors (``tests/core/loop`` -> ``safeembodai_core/loop``)."""
    for tests, source in MIRROR.items():
        if folder == tests or folder.startswith(tests + "/"):
            return source + folder[len(tests):]
    return None


def source_modules(root: Path = REPO) -> dict[str, set[str]]:
    """Every module and package name under the mirrored source folders -> the folders holding it."""
    found: dict[str, set[str]] = {}
    for source in MIRROR.values():
        for path in (root / source).rglob("*.py"):
            if "__pycache__" in path.parts:
                continue
            folder = path.parent.relative_to(root).as_posix()
            if path.name == "__init__.py":
                found.setdefault(path.parent.name, set()).add(path.parent.parent.relative_to(root).as_posix())
            else:
                found.setdefault(path.stem, set()).add(folder)
    return found


def misplaced(paths: list[str], root: Path = REPO) -> list[str]:
    """Test files outside a folder that mirrors an existing source package (or tests/meta)."""
    problems = []
    for path in paths:
        folder = str(PurePosixPath(path).parent)
        if pending(path) or folder == META:
            continue
        source = mirrored(folder)
        if source is None:
            problems.append(f"{path}: tests/{folder.split('/')[1]}/ mirrors no source folder")
        elif not (root / source / "__init__.py").exists():
            problems.append(f"{path}: {source}/ is not a source package")
    return problems


def in_the_wrong_package(paths: list[str], root: Path = REPO) -> list[str]:
    """``test_<name>.py`` where <name> is a module or package of another source folder than the one the
    file's folder mirrors (tests/backends/test_perception.py), or a top-level test of a subpackage
    (tests/core/test_scenario_loading.py: tests/core/scenario/)."""
    modules = source_modules(root)
    problems = []
    for path in paths:
        pure = PurePosixPath(path)
        source = mirrored(str(pure.parent))
        if pending(path) or source is None:
            continue
        name = pure.stem[len("test_"):]
        homes = modules.get(name, set())
        if homes and source not in homes and name != PurePosixPath(source).name:
            problems.append(f"{path}: {name} is in {', '.join(sorted(homes))}, not {source}")
        subpackages = {p.name for p in (root / source).iterdir() if (p / "__init__.py").exists()}
        for sub in subpackages:
            if name == sub or name.startswith(sub + "_"):
                if sub != PurePosixPath(source).name:
                    problems.append(f"{path}: tests {source}/{sub}, so belongs in {pure.parent}/{sub}/")
    return problems


def history_in_names(paths: list[str], root: Path = REPO) -> list[str]:
    problems = [f"{p}: the file name" for p in paths if HISTORY.search(PurePosixPath(p).stem[len("test_"):])]
    for path in paths:
        if not (root / path).exists():
            continue
        tree = ast.parse((root / path).read_text(encoding="utf-8"))
        for node in ast.walk(tree):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) \
                    and node.name.lower().startswith(("test", "Test".lower())) and HISTORY.search(node.name.lower()):
                problems.append(f"{path}: {node.name}")
    return problems


def same_name_same_module(paths: list[str]) -> list[str]:
    """Two test files of one name whose folders mirror the same source folder (pending ones counted at
    their target): one module tested in two places."""
    seen: dict[tuple[str, str], str] = {}
    problems = []
    for path in paths:
        pure = PurePosixPath(path)
        folder = str(pure.parent)
        for old, new in PENDING.items():
            if path == old or path.startswith(old + "/"):
                folder = new.split(" ")[0] + folder[len(old):] if path != old else new.split(" ")[0]
        key = (mirrored(folder) or folder, pure.name)
        if key in seen:
            problems.append(f"{path} and {seen[key]} both test {key[0]}/{pure.stem[len('test_'):]}")
        seen.setdefault(key, path)
    return problems


def test_the_mirror_points_at_source_folders_that_exist():
    for source in MIRROR.values():
        assert (REPO / source / "__init__.py").exists(), source


def test_every_test_file_lives_in_a_folder_that_mirrors_a_source_package():
    assert misplaced(all_test_files()) == []


def test_a_test_named_after_a_module_lives_in_that_modules_folder():
    assert in_the_wrong_package(all_test_files()) == []


def test_no_test_file_or_test_name_carries_history():
    assert history_in_names(all_test_files()) == []


def test_no_module_is_tested_by_two_files_of_the_same_name():
    assert same_name_same_module(all_test_files()) == []


def test_helpers_live_in_tests_support_and_it_holds_no_tests():
    assert [p for p in helper_files() if not p.startswith(SUPPORT + "/") and not pending(p)] == []
    assert [p for p in all_test_files() if p.startswith(SUPPORT + "/")] == []


def test_pending_moves_are_still_pending():
    """Drop an entry of PENDING once it has moved (its checks then apply to it)."""
    for path, target in PENDING.items():
        assert (REPO / path).exists(), f"{path} has moved: drop it from PENDING"
        assert mirrored(target.split(" ")[0]) or target.startswith(META), target


def test_the_layout_this_one_replaced_fails_the_checks(monkeypatch):
    """A sample of the old paths: every check above finds something in it."""
    old = ["tests/attacks/test_lidar_spoof.py", "tests/backends/test_perception.py",
           "tests/defences/test_validator_rules.py", "tests/core/test_scenario_loading.py",
           "tests/core/test_cli_ablate.py", "tests/core/test_response_parser.py",
           "tests/integrations/test_gym.py", "tests/core/test_lint.py",
           "tests/plugins/backends/test_perception.py", "tests/plugins/validators/test_issue_10_run.py",
           "tests/core/view/test_site.py"]
    assert misplaced(old) != []
    assert "tests/attacks/test_lidar_spoof.py: tests/attacks/ mirrors no source folder" in misplaced(old)
    assert any("test_scenario_loading" in p for p in in_the_wrong_package(old))
    assert any("tests/plugins/backends/test_perception.py" in p for p in in_the_wrong_package(old))
    assert history_in_names(old) == ["tests/plugins/validators/test_issue_10_run.py: the file name"]
    monkeypatch.setitem(PENDING, "tests/view", "tests/core/view")  # a folder still to move counts at its target
    assert same_name_same_module(old + ["tests/view/test_site.py"]) != []
