"""Loading plugins: built-ins, entry points, allow/block lists, bad plugins named, isolation."""

from __future__ import annotations

import tomllib
import types

import pytest
from pydantic import BaseModel, ConfigDict

from safeembodai_core import hookimpl
from safeembodai_core.errors import PluginError
from safeembodai_core.plugin.manager import builtin_plugins, load_plugins
from safeembodai_core.plugin.registry import ComponentRegistry


class _Opts(BaseModel):
    model_config = ConfigDict(extra="forbid")


def _plugin(name: str, **hooks) -> types.SimpleNamespace:
    plugin = types.ModuleType(name)
    for hook_name, function in hooks.items():
        setattr(plugin, hook_name, hookimpl(function))
    return plugin


def test_builtins_are_the_entry_points_declared_in_pyproject(repo):
    declared = tomllib.loads((repo / "pyproject.toml").read_text())["project"]["entry-points"]["safeembodai"]
    assert dict(builtin_plugins()) == declared


def test_every_builtin_loads_from_its_entry_point_and_reports_its_origin(plugins):
    names = {row["name"]: row for row in plugins.describe()}
    for name, module in builtin_plugins():
        assert names[name]["source"] == "built-in"
        assert names[name]["module"] == module
        assert names[name]["distribution"].startswith("safeembodai ")
    assert "validator:lidar_clearance" in names["validators"]["components"]
    assert "register_validators" in names["validators"]["hooks"]


def test_fresh_manager_per_call_keeps_runs_isolated():
    extra = _plugin("extra_validators", register_validators=lambda register: register(
        "only_here", lambda o, c: None, options=_Opts))
    with_extra = load_plugins([extra], environ={})
    without = load_plugins(environ={})
    assert "only_here" in with_extra.registry.names("validator")
    assert "only_here" not in without.registry.names("validator")


def test_disable_and_load_lists_from_the_environment():
    # the built-ins alone (entry_points=False): a third-party plugin installed beside them, as the docs'
    # example plugin is in CI, registers validators of its own that this list does not name
    blocked = load_plugins(environ={"SAFEEMBODAI_DISABLE_PLUGINS": "validators, attackers"}, entry_points=False)
    assert blocked.registry.names("validator") == []
    assert blocked.registry.names("attacker") == []
    assert "jinja" in blocked.registry.names("prompt_builder")
    only = load_plugins(environ={"SAFEEMBODAI_LOAD_PLUGINS": "validators"})
    assert [name for name, _ in only.pm.list_name_plugin() if _ is not None] == ["validators"]
    none = load_plugins(environ={"SAFEEMBODAI_LOAD_PLUGINS": ""})
    assert none.registry.all() == []


def test_misspelled_hook_is_rejected_naming_the_plugin():
    typo = _plugin("typo_plugin", register_validator=lambda register: None)
    with pytest.raises(PluginError, match="typo_plugin.*register_validator"):
        load_plugins([typo], environ={})


def test_same_component_name_from_two_plugins_names_both():
    first = _plugin("first", register_validators=lambda register: register("rule", lambda o, c: None, options=_Opts))
    second = _plugin("second", register_validators=lambda register: register("rule", lambda o, c: None, options=_Opts))
    plugins = load_plugins([first, second], builtins=False, environ={})
    with pytest.raises(PluginError) as error:
        plugins.registry
    assert "first" in str(error.value) and "second" in str(error.value)


def test_duplicate_of_a_builtin_name_is_an_error_too():
    clash = _plugin("clash", register_validators=lambda register: register(
        "lidar_clearance", lambda o, c: None, options=_Opts))
    with pytest.raises(PluginError, match="lidar_clearance' is already registered") as error:
        load_plugins([clash], environ={}).registry
    assert "'validators'" in str(error.value) and "'clash'" in str(error.value)


def test_options_model_must_forbid_extra_keys():
    class Loose(BaseModel):
        pass

    loose = _plugin("loose", register_validators=lambda register: register("loose_rule", lambda o, c: None,
                                                                           options=Loose))
    with pytest.raises(PluginError, match="extra='forbid'"):
        load_plugins([loose], builtins=False, environ={}).registry


def test_a_plugin_that_raises_is_reported_by_name():
    def broken(register):
        raise RuntimeError("boom")

    plugins = load_plugins([_plugin("broken_plugin", register_attackers=broken)], environ={})
    with pytest.raises(PluginError, match="broken_plugin.*register_attackers raised RuntimeError: boom"):
        plugins.registry


def test_a_factory_that_raises_is_reported_by_plugin_name():
    def factory(options, context):
        raise ValueError("no such device")

    plugin = _plugin("faulty", register_validators=lambda register: register("faulty_rule", factory, options=_Opts))
    registry = load_plugins([plugin], environ={}).registry
    with pytest.raises(PluginError,
                       match="faulty.*building validator 'faulty_rule' failed: ValueError: no such device"):
        registry.build("validator", "faulty_rule")


def test_a_lifecycle_hook_that_raises_is_reported_by_name():
    def after_trial(spec, result):
        raise KeyError("exporter down")

    plugins = load_plugins([_plugin("exporter", after_trial=after_trial)], environ={})
    with pytest.raises(PluginError, match="exporter.*after_trial raised KeyError"):
        plugins.notify("after_trial", spec=None, result=None)


class _EntryPoint:
    """An installed entry point as importlib.metadata gives it: name, value, its distribution, load()."""

    def __init__(self, name: str, value: str, distribution: str):
        self.name, self.value = name, value
        self.dist = types.SimpleNamespace(name=distribution, version="1.0")

    def load(self):
        import importlib

        return importlib.import_module(self.value)


def test_a_plugin_module_that_fails_to_import_is_named(monkeypatch):
    import safeembodai_core.plugin.manager as manager

    monkeypatch.setattr(manager, "_entry_points", lambda: [
        _EntryPoint("ghost", "safeembodai_plugins.does_not_exist", "safeembodai")])
    with pytest.raises(PluginError, match="ghost.*failed to load entry point 'safeembodai_plugins.does_not_exist'"):
        manager.load_plugins(environ={})


def test_without_the_packages_entry_points_no_builtin_loads_and_the_error_says_to_install(monkeypatch):
    import safeembodai_core.plugin.manager as manager

    monkeypatch.setattr(manager, "_entry_points", lambda: [
        _EntryPoint("example", "safeembodai_plugins.validators", "safeembodai-example-plugin")])
    with pytest.raises(PluginError, match="no built-in plugins.*pip install -e"):
        manager.load_plugins(environ={})
    only_theirs = manager.load_plugins(environ={}, builtins=False)
    assert [row["source"] for row in only_theirs.describe()] == ["entry point"]


def test_a_third_party_entry_point_cannot_take_a_builtins_name(monkeypatch):
    import safeembodai_core.plugin.manager as manager

    ours = [ep for ep in manager._entry_points() if manager._is_builtin(ep)]
    theirs = _EntryPoint("validators", "safeembodai_plugins.attackers", "someone-else")
    monkeypatch.setattr(manager, "_entry_points", lambda: [theirs, *ours])  # theirs listed first
    with pytest.raises(PluginError,
                       match="validators.*uses the name of the plugin from 'safeembodai_plugins.validators'"):
        manager.load_plugins(environ={})


def test_unknown_component_lists_the_registered_ones_with_a_hint(plugins):
    from safeembodai_core.errors import ComponentError

    with pytest.raises(ComponentError, match="Did you mean 'lidar_clearance'") as error:
        plugins.registry.get("validator", "lidar_clearence")
    assert "command_limits" in str(error.value)


def test_options_errors_name_component_and_key(plugins):
    from safeembodai_core.plugin.registry import ComponentOptionsError

    with pytest.raises(ComponentOptionsError) as error:
        plugins.registry.validate_options("validator", "lidar_clearance", {"half_angle_deg": -1, "bogus": 1})
    message = str(error.value)
    assert "lidar_clearance" in message and "half_angle_deg" in message and "bogus" in message


def test_trace_plugins_logs_each_hook_call(capsys):
    from safeembodai_core.logs import configure_logging

    configure_logging("debug")
    try:
        load_plugins(environ={"SAFEEMBODAI_TRACE_PLUGINS": "1"}).registry
    finally:
        configure_logging("warning")
    err = capsys.readouterr().err
    assert "hook.call" in err and "register_validators" in err and "plugin=validators" in err


def test_registry_is_empty_without_plugins():
    assert ComponentRegistry().all() == []
