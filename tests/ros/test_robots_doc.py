"""docs/robots.md runs as written: its Python examples, and its commands in a scratch folder."""

from __future__ import annotations

import re
import shlex

import pytest

from safeembodai_core.cli import cli


@pytest.fixture(scope="module")
def page(repo) -> str:
    return (repo / "docs" / "robots.md").read_text(encoding="utf-8")


def blocks(text: str, language: str) -> list[str]:
    return re.findall(rf"```{language}\n(.*?)```", text, re.S)


def test_the_python_examples_run(page, capsys):
    examples = blocks(page, "python")
    assert len(examples) == 2
    for example in examples:
        exec(compile(example, "docs/robots.md", "exec"), {"__name__": "docs_example"})
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("False ") and 0.0 < float(out[0].split()[1]) < 2.0
    assert out[1].startswith("twist linear.x 0.3 m/s") and "refused; at most" in out[1]
    assert out[2].startswith("1 of 1 refused: ")


def test_the_commands_run_in_order(page, repo, tmp_path, monkeypatch, cli_runner):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "scenarios").symlink_to(repo / "scenarios")
    commands = [line for block in blocks(page, "bash") for line in block.splitlines() if line.strip()]
    assert len(commands) == 4
    for line in commands:
        words = shlex.split(line)
        assert words[0] == "safeembodai"
        done = cli_runner.invoke(cli, words[1:])
        assert done.exit_code == 0, (line, done.output, done.exception)
    assert '"verdicts"' in done.output  # the last one printed JSON
