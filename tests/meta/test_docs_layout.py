"""The documentation's layout: reference and evidence apart.

Reference pages -- every page directly under docs/: what a component does, its options, short
examples, its failure modes -- stay short. Measurements, tuning tables and their history live under
docs/evidence/, and every evidence page is linked from a reference page or the README. Every
relative link of README.md and docs/**/*.md reaches an existing file and, with an ``#anchor``, a
heading of that file (GitHub's slugs). The YAML examples of the pages split off the long reference
pages are valid scenario parts, as those of defences.md and backends.md are
(tests/meta/test_docs_components.py)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import yaml

from safeembodai_core.scenario import parse_scenario

REPO = Path(__file__).resolve().parents[2]
DOCS = REPO / "docs"
MAX_LINES = 300
#: Reference pages allowed more than MAX_LINES, each with the reason it cannot be split. None today.
LONG_PAGES: dict[str, str] = {}
#: Pages that took the details of defences.md, backends.md and environments.md (their YAML is checked here).
SPLIT_OFF = ["backend_calls.md", "local_models.md", "parsing.md", "prompts.md", "rooms.md", "state.md",
             "validation.md"]

FENCE_OPEN = re.compile(r"^ {0,3}(`{3,}|~{3,})")
CODE_SPAN = re.compile(r"(`+)(?:(?!\n[ \t]*\n).)+?(?<!`)\1(?!`)", re.S)
LINK = re.compile(r"\[(?:[^\[\]]|\[[^\[\]]*\])*\]\(\s*<?([^)\s>]+)>?(?:\s+\"[^\"]*\")?\s*\)")
HEADING = re.compile(r"^ {0,3}(#{1,6})[ \t]+(.*?)(?:[ \t]+#+)?[ \t]*$")


def reference_pages() -> list[Path]:
    return sorted(DOCS.glob("*.md"))


def evidence_pages() -> list[Path]:
    return sorted((DOCS / "evidence").rglob("*.md"))


def all_pages() -> list[Path]:
    return [REPO / "README.md", *sorted(DOCS.rglob("*.md"))]


def name(path: Path) -> str:
    return str(path.relative_to(REPO))


def prose(text: str) -> str:
    """The text outside fenced code blocks (each fenced line left blank, so line numbers hold)."""
    lines, fence = [], None
    for line in text.split("\n"):
        if fence is None:
            opening = FENCE_OPEN.match(line)
            if opening:
                fence = opening.group(1)
                lines.append("")
                continue
            lines.append(line)
        else:
            if re.match(rf"^ {{0,3}}{re.escape(fence[0])}{{{len(fence)},}}[ \t]*$", line):
                fence = None
            lines.append("")
    return "\n".join(lines)


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: its text (link targets and markup dropped), lowercase,
    punctuation removed, each space a '-'."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)
    return re.sub(r"[^\w\- ]", "", text.strip().lower()).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    found: set[str] = set()
    seen: dict[str, int] = {}
    for line in prose(path.read_text(encoding="utf-8")).split("\n"):
        match = HEADING.match(line)
        if not match:
            continue
        base = slug(match.group(2))
        count = seen.get(base, 0)
        seen[base] = count + 1
        found.add(base if count == 0 else f"{base}-{count}")
    return found


def links(path: Path) -> list[str]:
    """Targets of the page's Markdown links and images, outside code (fenced or inline)."""
    text = CODE_SPAN.sub("", prose(path.read_text(encoding="utf-8")))
    return LINK.findall(text)


def relative(target: str) -> bool:
    return not re.match(r"^[A-Za-z][A-Za-z0-9+.-]*:", target) and not target.startswith("//")


# -- the check's own pieces ---------------------------------------------------------------------


def test_slugs_are_githubs():
    assert slug("`moving_obstacles`: movers' possible courses from consecutive scans") == \
        "moving_obstacles-movers-possible-courses-from-consecutive-scans"
    assert slug("Mover families (`labbot_family`)") == "mover-families-labbot_family"
    assert slug("The pilot's retries, and the re-tune that followed (seeds 5 and 6)") == \
        "the-pilots-retries-and-the-re-tune-that-followed-seeds-5-and-6"
    assert slug("Local models: llama.cpp, Ollama, vLLM") == "local-models-llamacpp-ollama-vllm"
    assert slug("Options of `gpt-4o`, `litellm` and `local`") == "options-of-gpt-4o-litellm-and-local"


def test_links_and_headings_in_code_do_not_count(tmp_path):
    page = tmp_path / "page.md"
    page.write_text("# Title\n\nSee [a](a.md#x) and `[b](b.md)`.\n\n```md\n# Not a heading\n[c](c.md)\n```\n\n"
                    "## Title\n\n[wrapped\ntext](d.md) ![pic](img.png) [web](https://example.org/x.md)\n")
    assert links(page) == ["a.md#x", "d.md", "img.png", "https://example.org/x.md"]
    assert anchors(page) == {"title", "title-1"}
    assert not relative("https://example.org/x.md") and relative("evidence/x.md#y")


# -- the layout ----------------------------------------------------------------------------------


def test_the_pages_exist():
    names = {path.name for path in reference_pages()}
    assert {"defences.md", "backends.md", "environments.md", *SPLIT_OFF} <= names
    assert evidence_pages()


@pytest.mark.parametrize("path", reference_pages(), ids=name)
def test_reference_pages_are_short(path):
    lines = len(path.read_text(encoding="utf-8").splitlines())
    if path.name in LONG_PAGES:
        assert lines > MAX_LINES, f"{name(path)} fits in {MAX_LINES} lines now: drop it from LONG_PAGES"
        return
    assert lines <= MAX_LINES, (
        f"{name(path)} has {lines} lines, more than {MAX_LINES}: move measurements and their history to "
        f"docs/evidence/ (linked from the page), or details to a page of their own")


def test_long_page_exceptions_name_pages_and_reasons():
    for page, reason in LONG_PAGES.items():
        assert (DOCS / page).is_file(), page
        assert len(reason) > 20, f"{page}: say why it cannot be split"


@pytest.mark.parametrize("path", evidence_pages(), ids=name)
def test_every_evidence_page_is_linked_from_a_reference_page_or_the_readme(path):
    linking = []
    for page in [REPO / "README.md", *reference_pages()]:
        for target in links(page):
            file = target.split("#", 1)[0]
            if relative(target) and file and (page.parent / file).resolve() == path.resolve():
                linking.append(name(page))
    assert linking, f"{name(path)} is linked from no reference page (docs/*.md) and not from README.md"


@pytest.mark.parametrize("path", all_pages(), ids=name)
def test_relative_links_reach_a_file_and_a_heading(path):
    broken = []
    for target in links(path):
        if not relative(target):
            continue
        file, _, anchor = target.partition("#")
        destination = (path.parent / file).resolve() if file else path
        if not destination.exists():
            broken.append(f"{target}: no such file")
        elif anchor and destination.suffix == ".md" and anchor not in anchors(destination):
            broken.append(f"{target}: no heading with the anchor #{anchor} in {name(destination)}")
    assert not broken, f"{name(path)}: " + "; ".join(broken)


# -- the split-off pages' examples ---------------------------------------------------------------


@pytest.mark.parametrize("page", SPLIT_OFF)
def test_yaml_examples_of_split_off_pages_are_valid_scenario_parts(plugins, page, tmp_path, monkeypatch):
    # the docs point template_dir at a user folder "my_prompts": give them one, as a user would
    shutil.copytree(REPO / "prompts", tmp_path / "my_prompts")
    monkeypatch.chdir(tmp_path)
    for block in re.findall(r"```yaml\n(.*?)```", (DOCS / page).read_text(encoding="utf-8"), re.S):
        scenario = {"name": "docs", "environments": ["flatland"], **yaml.safe_load(block)}
        parse_scenario(yaml.safe_dump(scenario), f"docs/{page}", registry=plugins.registry)
