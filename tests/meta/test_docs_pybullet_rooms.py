"""docs/environments.md documents every room and option, and its Python example runs as written."""

from __future__ import annotations

import re

import pytest
from safeembodai_plugins.environments.pybullet_rooms.options import ROOMS


@pytest.fixture(scope="module")
def doc(repo) -> str:
    return (repo / "docs" / "environments.md").read_text()


def test_every_room_and_every_option_is_documented(doc):
    table = {match.group(1) for match in re.finditer(r"^\| `(\w+)`", doc, re.M)}
    for kind, (model, _) in ROOMS.items():
        assert kind in table, f"room {kind} missing from the docs' table"
        missing = sorted(set(model.model_fields) - table)
        assert not missing, f"options of {kind} missing from the options table: {missing}"


def test_the_python_example_runs(doc, capsys):
    blocks = re.findall(r"```python\n(.*?)```", doc, re.S)
    assert blocks
    for block in blocks:
        exec(compile(block, "docs/environments.md", "exec"), {"__name__": "docs_example"})
    out = capsys.readouterr().out
    assert "(240, 320, 3) 360" in out and "Outcome.COMPLETED" in out
