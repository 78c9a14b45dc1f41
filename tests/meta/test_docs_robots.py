"""docs/robots.md and docs/robot_file.md run as written: their Python examples, and robots.md's commands in a
scratch folder."""

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


def run_examples(text: str, where: str, count: int) -> None:
    examples = blocks(text, "python")
    assert len(examples) == count
    for example in examples:
        exec(compile(example, where, "exec"), {"__name__": "docs_example"})


def test_the_python_examples_run(page, repo, capsys):
    run_examples(page, "docs/robots.md", 3)
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "False 1.57"  # the footprint's front (250 mm) meets the return 720 mm ahead at 0.3 m/s
    assert out[1].startswith("0.235 approach: ") and "speed x0.783" in out[1]
    assert out[2:5] == ["forward", "limit 0.53", "stop"]  # the node: clear, slowed, the scan too old
    assert out[5].startswith("1 of 1 refused: ")
    run_examples((repo / "docs" / "robot_file.md").read_text(encoding="utf-8"), "docs/robot_file.md", 1)
    assert capsys.readouterr().out.splitlines() == ["unknown False 0.03", "no_return True 1.00"]  # nulls, both ways


def test_the_robot_file_shown_is_the_shipped_example_and_reads(repo):
    from safeembodai_core.ros import read_robot_file

    page = (repo / "docs" / "robot_file.md").read_text(encoding="utf-8")
    shown = blocks(page, "yaml")
    example = repo / "docs" / "examples" / "robot.yaml"
    assert shown == [example.read_text(encoding="utf-8")]
    robot = read_robot_file(example)
    start = page.index("## The robot file")
    end = page.find("\n## ", start)
    section = page[start:end if end != -1 else len(page)]
    documented = re.findall(r"^\| `([\w.<>]+)` \|", section, re.M)
    assert set(type(robot).model_fields) == {name.split(".")[0] for name in documented}
    for name in type(robot.velocity_smoother).model_fields:
        assert f"velocity_smoother.{name}" in documented
    for name in type(robot.source()).model_fields:
        assert f"scans.<topic>.{name}" in documented


@pytest.mark.slow
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
