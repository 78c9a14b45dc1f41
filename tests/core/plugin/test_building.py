"""Building components: every part of the core builds through one call (the registry's ``build_ref``), and
what the factory is told."""

from __future__ import annotations

import ast
from pathlib import Path

from pydantic import BaseModel, ConfigDict

from safeembodai_core import hookimpl
from safeembodai_core.plugin.building import ComponentBuilder
from safeembodai_core.plugin.refs import ComponentRef
from safeembodai_core.testing import inline_plugins, tiny_scenario

CORE = Path(__file__).resolve().parents[3] / "safeembodai_core"


class _Options(BaseModel):
    model_config = ConfigDict(extra="forbid")
    size: int = 1


def _recording_plugin(seen: list):
    class Recorder:
        @hookimpl
        def register_validators(self, register):
            register("recorded", lambda options, context: seen.append((options, context)) or object(), options=_Options)

    return Recorder()


def test_the_factory_is_told_the_refs_key_the_seed_and_the_run_folder():
    seen: list = []
    plugins = inline_plugins(_recording_plugin(seen))
    plugins.registry.build_ref("validator", ComponentRef(use="recorded", options={"size": 3}, label="mine"),
                               seed=7, run_dir="/tmp/run")
    options, context = seen[0]
    assert options.size == 3
    assert (context.component, context.kind, context.label, context.seed, context.run_dir) == (
        "recorded", "validator", "mine", 7, "/tmp/run")


def test_the_scenario_builder_builds_through_the_same_call():
    seen: list = []
    plugins = inline_plugins(_recording_plugin(seen))
    builder = ComponentBuilder(tiny_scenario(), plugins, run_dir="/tmp/run")
    builder.build("validator", ComponentRef(use="recorded"), seed=2, only_to_describe=True)
    _, context = seen[0]
    assert (context.label, context.seed, context.run_dir, context.only_to_describe) == ("recorded", 2, "/tmp/run", True)


def test_no_module_of_the_core_builds_a_component_but_through_build_ref():
    callers = []
    for path in CORE.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute) and node.func.attr == "build"
                    and isinstance(node.func.value, (ast.Attribute, ast.Name))
                    and (getattr(node.func.value, "attr", None) or getattr(node.func.value, "id", None)) == "registry"):
                callers.append(path.relative_to(CORE).as_posix())
    assert callers == []  # registry.build(kind, name, options, context): each caller made its own context
