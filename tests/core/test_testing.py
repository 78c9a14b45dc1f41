"""The helpers ``safeembodai_core.testing`` gives plugin authors."""

from __future__ import annotations

import inspect

from safeembodai_core.contracts.components import Environment
from safeembodai_core.testing import CorridorWorld, StagedWorld


def test_a_staged_world_passes_every_environment_method_to_its_room():
    methods = [name for name, _ in inspect.getmembers(Environment, inspect.isfunction) if not name.startswith("_")]
    assert "another_call" in methods and "snapshot" in methods
    assert [name for name in methods if name not in vars(StagedWorld)] == []


def test_a_staged_world_tells_its_room_of_each_retry():
    calls = []

    class Room(CorridorWorld):
        def another_call(self) -> None:
            calls.append("retry")

    staged = StagedWorld(Room())
    staged.another_call()
    assert calls == ["retry"]
