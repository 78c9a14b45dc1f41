"""Meta-tests: every public name a plugin author or library user meets is documented in docs/
(the way every hook is, see test_hook_hygiene.py), and the surfaces a plugin needs are spelt out."""

from __future__ import annotations

import dataclasses
import inspect
import re

import pytest

import safeembodai_core
from safeembodai_core import testing

CORE = sorted(safeembodai_core.__all__)
KIT = sorted(testing.__all__)


@pytest.fixture(scope="module")
def docs(repo) -> str:
    return "\n".join(path.read_text() for path in sorted((repo / "docs").rglob("*.md")))


def mentioned(name: str, text: str) -> bool:
    """``name`` appears as code in running text (inline backticks), not only inside a code block."""
    return re.search(rf"`[^`\n]*(?<![\w]){re.escape(name)}(?![\w])[^`\n]*`", text) is not None


def section(text: str, heading: str) -> str:
    start = text.index(heading)
    level = heading.split(" ")[0]
    following = re.search(rf"^{level} ", text[start + len(heading):], re.M)
    return text[start: start + len(heading) + following.start()] if following else text[start:]


@pytest.mark.parametrize("name", CORE)
def test_every_public_name_of_the_package_is_documented(name, docs):
    assert hasattr(safeembodai_core, name), f"safeembodai_core.__all__ lists {name!r}, which does not import"
    assert mentioned(name, docs), f"safeembodai_core.{name} is public but no page of docs/ mentions `{name}`"


@pytest.mark.parametrize("name", KIT)
def test_every_public_name_of_the_testing_kit_is_documented(name, docs):
    assert mentioned(name, docs), f"safeembodai_core.testing.{name} is public but no page of docs/ mentions `{name}`"


def test_the_testing_kit_lists_every_public_name_it_defines():
    defined = {name for name, value in vars(testing).items()
               if not name.startswith("_") and getattr(value, "__module__", None) == testing.__name__}
    assert defined == set(testing.__all__)


def test_the_documented_check_finds_what_is_missing():
    assert mentioned("Guard", "use `Guard(rules=...)` here")
    assert not mentioned("Guard", "```python\nGuard()\n```") and not mentioned("Guard", "`GuardReport`")


# -- the surfaces a plugin needs ---------------------------------------------------------------


def test_validation_context_attack_surface_and_build_context_are_spelt_out(repo):
    from safeembodai_core import AttackSurface, BuildContext, ValidationContext

    hooks = (repo / "docs" / "plugin_hooks.md").read_text()
    members = [name for name, _ in inspect.getmembers(ValidationContext) if not name.startswith("_")]
    for cls, names in ((ValidationContext, members), (AttackSurface, []), (BuildContext, [])):
        for name in [f.name for f in dataclasses.fields(cls)] + names:
            assert re.search(rf"^\| `{name}[`(]", hooks, re.M), (
                f"{cls.__name__}.{name} has no row in docs/plugin_hooks.md")
    assert "`(x_mm, y_mm, heading_deg)`" in hooks and "scan frame" in hooks  # the offset's order and frame
    assert "`LidarScan(ranges_mm, max_range_mm)`" in hooks
    assert "`BuildContext(component, kind, seed=0, label=None, run_dir=None, only_to_describe=False)`" in hooks
    assert "`safeembodai ablate --out DIR`" in hooks


def test_trial_results_attack_counters_are_documented(repo):
    from safeembodai_core.models import TrialResult

    library = (repo / "docs" / "library.md").read_text()
    counters = [name for name in TrialResult.model_fields if "attack" in name or name.startswith("flagged")]
    assert set(counters) == {"attacked_steps", "flagged_steps", "flagged_attacked_steps"}
    for name in counters:
        assert re.search(rf"^\| `{name}` \|", library, re.M), f"TrialResult.{name} is not in docs/library.md"


def test_the_flatland_world_documents_its_frame_and_every_option(repo, plugins):
    flatland = section((repo / "docs" / "environments.md").read_text(), "## The flatland world")
    assert "x east, y north" in flatland and "counter-clockwise from +x" in flatland
    model = plugins.registry.get("environment", "flatland").options
    for name, field in model.model_fields.items():
        row = re.search(rf"^\| `{name}` \| ([^|]+) \|", flatland, re.M)
        assert row, f"flatland option {name} is not in its table"
        assert float(row.group(1).replace(" ", "")) == field.default, f"flatland option {name}: default differs"


def test_run_tiny_trial_takes_any_top_level_key_as_documented(repo):
    plugins_md = (repo / "docs" / "plugins.md").read_text()
    assert 'run_tiny_trial(backend={"use": "mock"})' in plugins_md
    replies = [testing.answer(testing.turn(20)), testing.answer(testing.turn(25))]
    _, steps = testing.run_tiny_trial([testing.answer(testing.turn(10))], max_steps=2,
                                      backend={"use": "scripted", "options": {"responses": replies}})
    assert [step.planned[0].angle for step in steps] == [20, 25]


def test_the_geofence_shown_is_the_example_plugins_one_class_of_under_40_lines(repo):
    shown = re.search(r"```python\n(.*?class Geofence\(Validator\):.*?)```", (repo / "docs" / "plugins.md").read_text(),
                      re.S)
    assert shown
    source = (repo / "docs" / "examples" / "safeembodai-example-plugin" / "safeembodai_example"
              / "rules.py").read_text()
    shipped = re.search(r"^class Geofence\(Validator\):.*?(?=^class |\Z)", source, re.S | re.M).group(0).rstrip()
    assert shipped in shown.group(1)
    assert len(shipped.splitlines()) < 40
    hooks = (repo / "docs" / "plugin_hooks.md").read_text()
    for used in set(re.findall(r"context\.(\w+)", shipped)):
        assert mentioned(used, hooks), f"the geofence uses context.{used}, which docs/plugin_hooks.md does not name"


def test_the_mocks_cues_are_listed_in_the_docs_and_read_as_listed(repo):
    from safeembodai_plugins.backends.mock import instruction as mock_instruction

    cues = section((repo / "docs" / "backends.md").read_text(), "### The cues it reads")
    rows = {m.group(1): re.findall(r"`([^`]+)`", m.group(2))
            for m in re.finditer(r"^\| `(\w+)` \| ([^|]+) \|", cues, re.M)}
    assert set(rows) == set(mock_instruction.INTENTS)
    for intent, phrases in rows.items():
        for phrase in phrases:
            reading = mock_instruction.read_instruction(f"Fine. Then {phrase} please.")
            assert reading.intent == intent, f"documented cue {phrase!r} of {intent} reads as {reading.intent}"
    for intent, pattern in mock_instruction._CUES:
        for alternative in _top_level_alternatives(pattern.pattern):
            assert any(re.search(alternative, phrase, re.I) for phrase in rows[intent]), (
                f"the mock's cue /{alternative}/ ({intent}) is not listed in docs/backends.md")


def _top_level_alternatives(pattern: str) -> list[str]:
    parts, depth, start = [], 0, 0
    for index, char in enumerate(pattern):
        if char == "\\":
            continue
        if char == "(" and pattern[index - 1: index] != "\\":
            depth += 1
        elif char == ")" and pattern[index - 1: index] != "\\":
            depth -= 1
        elif char == "|" and depth == 0:
            parts.append(pattern[start:index])
            start = index + 1
    return parts + [pattern[start:]]
