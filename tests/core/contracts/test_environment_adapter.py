"""Environments behind a declared adapter, as backends are: one table says which methods are optional and
what their default does, a duck-typed environment gets them declared, and nothing is left undeclared."""

from __future__ import annotations

import inspect

import pytest

from safeembodai_core.contracts.components import (
    OPTIONAL_ENVIRONMENT_METHODS, Environment, _DeclaredEnvironment, as_environment,
)
from safeembodai_core.testing import CorridorWorld

REQUIRED = {"reset", "observe", "execute", "outcome"}


def public_methods(cls) -> set[str]:
    return {name for name, _ in inspect.getmembers(cls, inspect.isfunction) if not name.startswith("_")}


def test_every_method_of_an_environment_is_required_or_declared_optional_with_its_default():
    assert public_methods(Environment) == REQUIRED | set(OPTIONAL_ENVIRONMENT_METHODS)
    assert all(len(default) > 10 for default in OPTIONAL_ENVIRONMENT_METHODS.values())
    assert set(vars(_DeclaredEnvironment)) >= public_methods(Environment)  # the adapter passes each one on


class DuckRoom:
    """A plugin's world that does not subclass Environment: the required four, and a drive of its own."""

    def __init__(self) -> None:
        self.world = CorridorWorld()
        self.driven: list[tuple[float, float, float]] = []

    def reset(self, seed):
        return self.world.reset(seed)

    def observe(self):
        return self.world.observe()

    def execute(self, signal):
        return self.world.execute(signal)

    def outcome(self):
        return self.world.outcome()

    def drive(self, linear_mm_s, angular_deg_s, seconds):
        self.driven.append((linear_mm_s, angular_deg_s, seconds))


def test_a_duck_typed_environment_gets_its_own_methods_and_the_defaults_for_the_rest():
    room = DuckRoom()
    declared = as_environment(room)
    assert isinstance(declared, Environment) and as_environment(declared) is declared
    declared.reset(1)
    declared.drive(100.0, 0.0, 0.5)
    assert room.driven == [(100.0, 0.0, 0.5)]
    assert declared.sense() is None and declared.snapshot() is None and declared.another_call() is None


def test_an_object_without_the_required_methods_is_refused_by_name():
    with pytest.raises(TypeError, match="execute, outcome"):
        as_environment(type("Half", (), {"reset": lambda self, seed: None, "observe": lambda self: None})())


def test_the_registry_declares_what_a_plugins_factory_returns():
    from pydantic import BaseModel, ConfigDict

    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.plugin.registry import ComponentInfo

    class NoOptions(BaseModel):
        model_config = ConfigDict(extra="forbid")

    registry = load_plugins(environ={}).registry
    registry.add(ComponentInfo("environment", "duck_room", "test", lambda options, context: DuckRoom(), NoOptions))
    assert isinstance(registry.build("environment", "duck_room", {}), _DeclaredEnvironment)
