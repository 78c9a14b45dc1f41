"""``registry.lazy``: the built-in plugins register by name and import their implementation only when
a component is built; a factory that cannot import fails as ``from module import name`` would."""

from __future__ import annotations

import subprocess
import sys

import pytest

from safeembodai_core.contracts.components import BuildContext
from safeembodai_core.errors import PluginError
from safeembodai_core.plugin.registry import ComponentInfo, ComponentRegistry, NoOptions, lazy

#: registration module -> the implementation modules it must not import by registering
LAZY = {
    "safeembodai_plugins.validators": ("rules", "sweep", "moving"),
    "safeembodai_plugins.attackers": ("injection", "spoof", "poisoning"),
    "safeembodai_plugins.perception": ("render",),
    "safeembodai_plugins.prompting": ("builder",),
    "safeembodai_plugins.environments.flatland": ("world",),
    "safeembodai_plugins.environments.pybullet_rooms": ("world",),
}


class Built:
    def __init__(self, *args):
        self.args = args


def test_lazy_imports_on_build_and_passes_leading_arguments_then_the_options():
    factory = lazy(__name__, "Built", "MO")
    options = NoOptions()
    built = factory(options, BuildContext(component="x", kind="environment"))
    assert isinstance(built, Built) and built.args == ("MO", options)
    assert factory.__name__ == "build_Built"


def test_a_missing_name_fails_like_from_import_and_is_reported_by_plugin():
    registry = ComponentRegistry()
    registry.add(ComponentInfo("validator", "ghost", "acme", lazy(__name__, "NoSuchRule"), NoOptions))
    registry.add(ComponentInfo("validator", "gone", "acme", lazy("acme_no_such_module.rules", "Rule"), NoOptions))
    with pytest.raises(ImportError, match=r"cannot import name 'NoSuchRule' from '.*test_lazy_factories'"):
        lazy(__name__, "NoSuchRule")(NoOptions(), BuildContext(component="ghost", kind="validator"))
    with pytest.raises(PluginError, match=r"building validator 'ghost' failed: ImportError: cannot import name"):
        registry.build("validator", "ghost")
    with pytest.raises(PluginError, match=r"building validator 'gone' failed: ModuleNotFoundError: No module named"):
        registry.build("validator", "gone")


def test_registering_the_builtins_imports_no_implementation_module():
    code = ("import importlib, sys\n"
            f"lazy = {LAZY!r}\n"
            "for package, modules in lazy.items():\n"
            "    importlib.import_module(package)\n"
            "loaded = [f'{p}.{m}' for p, ms in lazy.items() for m in ms if f'{p}.{m}' in sys.modules]\n"
            "assert not loaded, loaded\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr


def test_the_builtins_build_through_their_lazy_factories(plugins):
    registry = plugins.registry
    rule = registry.build("validator", "lidar_clearance")
    assert type(rule).__module__ == "safeembodai_plugins.validators.rules"
    assert type(registry.build("attacker", "prompt_injection")).__name__ == "PromptInjectionAttacker"
    assert type(registry.build("perception", "text")).__name__ == "TextPerception"
    assert type(registry.build("prompt_builder", "jinja")).__name__ == "JinjaPromptBuilder"
    world = registry.build("environment", "flatland")
    try:
        assert type(world).__name__ == "FlatlandWorld"
    finally:
        world.close()
