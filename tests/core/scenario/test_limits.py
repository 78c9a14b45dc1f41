"""No scenario file can hang or crash the loader: size, file type, nodes, depth and aliases are bounded.

Every refusal is a ScenarioError naming the file and the limit; the CLI prints it on one line.
"""

from __future__ import annotations

import os
import re
import stat
import sys

import pytest

from safeembodai_core.cli import cli, main
from safeembodai_core.errors import ScenarioError
from safeembodai_core.scenario import load_scenario, parse_scenario
from safeembodai_core.scenario import limits
from safeembodai_core.scenario.limits import MAX_BYTES, MAX_DEPTH, MAX_NODES, MAX_TEXT

pytestmark = pytest.mark.timeout(60)

MINIMAL = "name: tiny\nenvironments: [flatland]\n"
# "billion laughs": 9 ** 9 strings once expanded, from 10 short lines
ALIAS_BOMB = MINIMAL + "description:\n  a: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]\n" + "".join(
    f"  {b}: &{b} [{', '.join([f'*{a}'] * 9)}]\n" for a, b in zip("abcdefgh", "bcdefghi")
)
FLOW_DEEP = MINIMAL + "description: " + "[" * 100_000 + "]" * 100_000 + "\n"
BLOCK_DEEP = MINIMAL + "description:\n" + "".join(" " * (i + 1) + f"k{i}:\n" for i in range(300))
# each anchor wraps the one before in 30 more levels: few nodes, but deep once expanded
ALIAS_DEEP = MINIMAL + "description:\n  a0: &a0 " + "[" * 30 + "]" * 30 + "\n" + "".join(
    f"  a{i}: &a{i} {'[' * 30}*a{i - 1}{']' * 30}\n" for i in range(1, 5)
)

REFUSED_TEXTS = {  # text, line of the refusal, what is said about it
    "alias bomb": (ALIAS_BOMB, 9, rf"more than {MAX_NODES} YAML nodes once alias \*e is expanded"),
    "text bomb": (MINIMAL + "description:\n  a: &a " + "x" * 50_000 + "\n  b: [" + "*a, " * 100 + "]\n", 5,
                  rf"more than {MAX_TEXT} characters of text once alias \*a is expanded"),
    "recursive alias": (MINIMAL + "description: &a [*a]\n", 3, r"alias \*a is recursive"),
    "recursive alias in a mapping": (MINIMAL + "description: &a {again: *a}\n", 3, r"alias \*a is recursive"),
    "flow nesting": (FLOW_DEEP, 3, rf"nested deeper than {MAX_DEPTH} levels"),
    "block nesting": (BLOCK_DEEP, MAX_DEPTH + 2, rf"nested deeper than {MAX_DEPTH} levels"),
    "nesting through aliases": (ALIAS_DEEP, 6, rf"nested deeper than {MAX_DEPTH} levels once alias \*a1 is expanded"),
    "huge integer": (MINIMAL + "seed: " + "9" * 5000 + "\n", 3, r"not valid YAML: integer with more than 4300 digits"),
    "huge hex integer": (MINIMAL + "seed: 0x" + "f" * 200_000 + "\n", 3,
                         r"not valid YAML: integer with more than 4300 digits"),
    "impossible date": (MINIMAL + "description: 2024-13-45\n", 3, r"not valid YAML: invalid timestamp: month"),
    "NUL character": (MINIMAL + "description: a\x00b\n", 3, r"not valid YAML: special characters are not allowed"),
}


@pytest.mark.parametrize("case", REFUSED_TEXTS)
def test_hostile_yaml_is_refused_with_file_line_and_limit(case):
    text, line, message = REFUSED_TEXTS[case]
    with pytest.raises(ScenarioError, match=rf"^evil\.yaml:{line}: {message}"):
        parse_scenario(text, "evil.yaml")


def test_anchors_and_merges_within_the_limits_still_work():
    text = MINIMAL + "seed: 3\nlimits: &l {max_signals: 4}\narms:\n  baseline: {}\n  other: {<<: *l}\n"
    with pytest.raises(ScenarioError) as error:  # merged keys are named at the line that holds them
        parse_scenario(text, "demo.yaml")
    assert "demo.yaml:4: arms.other.max_signals: Extra inputs" in str(error.value)
    text = MINIMAL + "conditions:\n  a: &same {attackers: [prompt_injection]}\n  b: *same\n"
    assert list(parse_scenario(text, "demo.yaml").conditions) == ["a", "b"]


def test_overrides_are_bounded_like_the_file():
    bomb = "{" + ALIAS_BOMB.split("description:\n", 1)[1].replace("\n", ", ").strip(", ") + "}"
    cases = {
        f"description={bomb}": rf"^--set description: more than {MAX_NODES} YAML nodes once alias",
        "description=&a [*a]": r"^--set description: alias \*a is recursive",
        "environments.0.options.x=" + "[" * 100 + "]" * 100:
            rf"^--set environments.0.options.x: nested deeper than {MAX_DEPTH}",
        "environments.0.options." + ".".join(["x"] * 100) + "=1": rf"more than {MAX_DEPTH - 1} dotted names",
        "seed=" + "7" * 5000: r"^--set seed: not valid YAML: integer with more than 4300 digits",
    }
    for override, message in cases.items():
        with pytest.raises(ScenarioError, match=message):
            parse_scenario(MINIMAL, "demo.yaml", [override])


def _big_file(tmp_path):
    path = tmp_path / "big.yaml"
    with path.open("wb") as out:  # valid YAML all through: only the size check refuses it
        out.write(MINIMAL.encode())
        block = b"# padding" * 100 + b"\n"
        for _ in range(50 * 1024 * 1024 // len(block)):
            out.write(block)
    return path, r"is \d+ bytes; a scenario file may have at most 1048576 bytes \(1 MiB\)"


def _fifo(tmp_path):
    if not hasattr(os, "mkfifo"):
        pytest.skip("no FIFOs on this platform")
    path = tmp_path / "pipe.yaml"
    os.mkfifo(path)  # nobody ever writes to it: a blocking open would wait forever
    return path, r"is a FIFO \(named pipe\); a scenario must be a regular file"


def _dev_zero(tmp_path):
    if not os.path.exists("/dev/zero"):
        pytest.skip("no /dev/zero")
    return "/dev/zero", "is a character device; a scenario must be a regular file"


def _directory(tmp_path):
    return tmp_path, "is a directory; a scenario must be a regular file"


FILES = {"50 MB file": _big_file, "FIFO": _fifo, "/dev/zero": _dev_zero, "directory": _directory}


@pytest.mark.parametrize("kind", FILES)
def test_only_small_regular_files_are_read(kind, tmp_path):
    path, message = FILES[kind](tmp_path)
    with pytest.raises(ScenarioError, match=rf"^{str(path)}: {message}$"):
        load_scenario(path)


def test_a_file_at_the_size_limit_loads_and_one_byte_more_is_refused(tmp_path):
    path = tmp_path / "full.yaml"
    head = MINIMAL.encode()
    path.write_bytes(head + b"#" * (MAX_BYTES - len(head) - 1) + b"\n")
    assert load_scenario(path).name == "tiny"
    path.write_bytes(path.read_bytes() + b"\n")
    with pytest.raises(ScenarioError, match=r"is 1048577 bytes"):
        load_scenario(path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs on this platform")
def test_a_fifo_swapped_in_after_the_check_is_refused_without_blocking(tmp_path, monkeypatch):
    path = tmp_path / "swapped.yaml"
    os.mkfifo(path)
    check = limits._check_regular
    calls = []

    def passes_once(where, info):  # the check before opening saw a regular file; the one after must not
        calls.append(stat.S_IFMT(info.st_mode))
        if len(calls) > 1:
            check(where, info)

    monkeypatch.setattr(limits, "_check_regular", passes_once)
    with pytest.raises(ScenarioError, match="is a FIFO"):
        load_scenario(path)
    assert len(calls) == 2


def test_undecodable_file_is_named(tmp_path):
    path = tmp_path / "latin1.yaml"
    path.write_bytes(MINIMAL.encode() + "description: caf\xe9\n".encode("latin-1"))
    with pytest.raises(ScenarioError, match=r"latin1.yaml: cannot read scenario: not UTF-8"):
        load_scenario(path)


def _write(tmp_path, case):
    if case in FILES:
        return FILES[case](tmp_path)
    path = tmp_path / "evil.yaml"
    text, line, message = REFUSED_TEXTS[case]
    path.write_text(text, encoding="utf-8")
    return path, f":{line}: {message}"


@pytest.mark.parametrize("case", ["alias bomb", "recursive alias", "flow nesting", "block nesting",
                                  "50 MB file", "FIFO", "/dev/zero", "directory"])
def test_cli_refuses_in_one_line_without_a_traceback(case, tmp_path, cli_runner, capsys):
    path, message = _write(tmp_path, case)
    result = cli_runner.invoke(cli, ["run", str(path), "--out", str(tmp_path / "out")])
    assert result.exit_code != 0 and "Traceback" not in result.output
    if case == "directory":  # click's own check on SCENARIO refuses it first
        assert "is a directory" in result.output
        return
    assert isinstance(result.exception, ScenarioError), result.exception
    with pytest.raises(SystemExit) as done:
        main(["run", str(path), "--out", str(tmp_path / "out")])
    assert done.value.code == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"Error: {path}") and re.search(message, lines[0])
    assert not (tmp_path / "out").exists()


def test_recursion_limit_is_far_above_the_depth_limit():
    assert sys.getrecursionlimit() > 8 * MAX_DEPTH
