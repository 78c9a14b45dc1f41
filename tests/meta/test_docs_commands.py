"""Every ``safeembodai`` command line in README.md and docs/ names a command and options that exist,
with values the command accepts: each is parsed by the CLI itself (nothing is run). A path the
example names that does not exist here (``runs/mo-<time>``) is the reader's to have; anything else
a command refuses fails the test. (The Python examples run: test_docs_examples.py; docs/robots.md's
commands run: tests/meta/test_docs_robots.py.)"""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import click
import pytest

from safeembodai_core.cli import cli

REPO = Path(__file__).resolve().parents[2]
FENCE = re.compile(r"^( *)```[a-z]*\n(.*?)^\1```", re.M | re.S)


def command_lines() -> list[tuple[str, str]]:
    found = []
    for path in [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]:
        for _, block in FENCE.findall(path.read_text(encoding="utf-8")):
            for line in block.splitlines():
                line = line.strip().removeprefix("$ ")
                if line.startswith("safeembodai "):
                    found.append((str(path.relative_to(REPO)), line))
    return found


LINES = command_lines()


def test_the_docs_have_commands_to_check():
    assert len(LINES) >= 25
    assert {line.split()[1] for _, line in LINES} >= {"ablate", "run", "show", "view", "guard-bag", "export",
                                                      "report", "plugins"}


@pytest.mark.parametrize("page, line", LINES, ids=[f"{page}:{line[:50]}" for page, line in LINES])
def test_a_documented_command_parses(page, line):
    words = shlex.split(line, comments=True)
    parent = cli.make_context("safeembodai", words[1:], resilient_parsing=True)
    command = cli.get_command(parent, words[1])
    assert command is not None, f"{page}: no command {words[1]!r}"
    try:
        command.make_context(words[1], words[2:], parent=parent)
    except click.exceptions.Exit:  # --help
        pass
    except click.BadParameter as error:
        assert "does not exist" in str(error), f"{page}: {line}: {error}"
    except click.UsageError as error:
        pytest.fail(f"{page}: {line}: {error}")
