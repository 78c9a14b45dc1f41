"""Comments, docstrings and docs cite only what exists: every dotted ``safeembodai_*`` name and every
path of this repository they name is there, so a module renamed or moved cannot leave a reader
following a stale pointer."""

from __future__ import annotations

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
PACKAGES = {"safeembodai_core": "safeembodai_core", "safeembodai_plugins": "plugins",
            "safeembodai_prompts": "prompts"}
DOTTED = re.compile(r"\b(safeembodai_(?:core|plugins|prompts)(?:\.[A-Za-z_][A-Za-z0-9_]*)+)")
#: a path of this repository as cited: from one of its top-level folders, to a file with a suffix
PATH = re.compile(r"(?<![\w/.-])((?:safeembodai_core|plugins|bench|tests|scenarios|prompts|docs)/"
                  r"[\w/.-]*\w\.(?:py|md|yaml|j2))")
PLACEHOLDER = re.compile(r"\b[A-Z]{2,}\b")  # scenarios/NAME.yaml


def _sources() -> list[Path]:
    found = [*REPO.glob("safeembodai_core/**/*.py"), *REPO.glob("plugins/**/*.py"), *REPO.glob("bench/*.py"),
             *REPO.glob("docs/**/*.md"), REPO / "README.md"]
    return [path for path in found if "examples" not in path.relative_to(REPO).parts[:2]]


def _names_something(dotted: str) -> bool:
    """The longest prefix that is a module or package, and the rest (at most one attribute) defined in it."""
    parts = dotted.split(".")
    base = REPO / PACKAGES[parts[0]]
    for cut in range(len(parts), 0, -1):
        folder = base.joinpath(*parts[1:cut])
        source = folder.with_suffix(".py") if folder.with_suffix(".py").is_file() else folder / "__init__.py"
        if not source.is_file():
            continue
        rest = parts[cut:]
        if not rest:
            return True
        text = source.read_text(encoding="utf-8")
        return len(rest) <= 2 and re.search(rf"\b{re.escape(rest[0])}\b", text) is not None
    return False


#: the previous release's module paths, named on purpose (each still imports: tests/core/test_moved_modules.py)
MOVED_TABLE = REPO / "safeembodai_core" / "moved_modules.py"


def test_every_dotted_name_cited_exists():
    stale = sorted({f"{path.relative_to(REPO)}: {name}" for path in _sources() if path != MOVED_TABLE
                    for name in DOTTED.findall(path.read_text(encoding="utf-8"))
                    if not _names_something(name.rstrip("."))})
    assert not stale, "names cited that do not exist:\n" + "\n".join(stale)


def test_every_repository_path_cited_exists():
    stale = sorted({f"{path.relative_to(REPO)}: {cited}" for path in _sources()
                    for cited in PATH.findall(path.read_text(encoding="utf-8"))
                    if not PLACEHOLDER.search(cited) and not (REPO / cited).exists()})
    assert not stale, "paths cited that do not exist:\n" + "\n".join(stale)


def test_the_checks_see_a_stale_name_and_a_stale_path():
    assert not _names_something("safeembodai_core.models.chat_completion.reply_from_body")
    assert _names_something("safeembodai_core.models.chat_completion.reply_from_chat_completion")
    assert _names_something("safeembodai_core.ablation.plan")
    assert PATH.findall("see `safeembodai_core/loop/trial.py` and tests/meta/test_lint.py.") == [
        "safeembodai_core/loop/trial.py", "tests/meta/test_lint.py"]
