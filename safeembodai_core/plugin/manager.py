"""The plugin manager: which plugins a run uses and how they are loaded.

Every plugin is an entry point of the ``safeembodai`` group. The built-ins are the ones this
package declares (``pyproject.toml``, as a third party declares its own: :func:`builtin_plugins`);
they register first, then every other distribution's. Nothing is loaded at import time:
:func:`load_plugins` builds a fresh manager per call, so library users and tests never share state.

Environment variables:

* ``SAFEEMBODAI_LOAD_PLUGINS=a,b`` loads only the named plugins (set but empty: none);
* ``SAFEEMBODAI_DISABLE_PLUGINS=a,b`` blocks the named plugins;
* ``SAFEEMBODAI_TRACE_PLUGINS=1`` logs every hook call (plugin and hook) through structlog.
"""

from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from importlib import metadata
from typing import Any, Iterable, Mapping

from typing import TYPE_CHECKING

import pluggy

from .. import hookspecs
from ..errors import PluginError

if TYPE_CHECKING:
    from ..metrics.catalog import Metric
    from .registry import ComponentRegistry

ENTRY_POINT_GROUP = "safeembodai"

#: The distribution whose entry points in ENTRY_POINT_GROUP are the built-in plugins (pyproject.toml's
#: ``[project] name``): built-ins register through the same mechanism a third party uses.
DISTRIBUTION = "safeembodai"


def _entry_points() -> list[Any]:
    """Every installed entry point of ENTRY_POINT_GROUP (one distribution of each name)."""
    return list(metadata.entry_points(group=ENTRY_POINT_GROUP))


def _distribution(entry_point: Any) -> tuple[str, str]:
    """(name, version) of the distribution that declares ``entry_point`` ("" where unknown)."""
    dist = getattr(entry_point, "dist", None)
    return getattr(dist, "name", "") or "", getattr(dist, "version", "") or ""


def _is_builtin(entry_point: Any) -> bool:
    return re.sub(r"[-_.]+", "-", _distribution(entry_point)[0]).lower() == DISTRIBUTION


def builtin_plugins() -> tuple[tuple[str, str], ...]:
    """The built-in plugins as installed: (name, module) of each entry point this package declares."""
    return tuple((ep.name, ep.value) for ep in _entry_points() if _is_builtin(ep))


@dataclass(frozen=True)
class PluginOrigin:
    """Where a plugin came from, for ``safeembodai plugins``."""

    name: str
    source: str  # "built-in", "entry point" or "inline"
    module: str
    distribution: str = ""
    version: str = ""


def _names(value: str | None) -> set[str] | None:
    if value is None:
        return None
    return {part.strip() for part in value.split(",") if part.strip()}


@dataclass
class Plugins:
    """One run's plugins: the pluggy manager, where each plugin came from, and its components."""

    pm: pluggy.PluginManager
    origins: dict[str, PluginOrigin] = field(default_factory=dict)
    trace: bool = False
    _registry: "ComponentRegistry | None" = None
    _metrics: "tuple[Metric, ...] | None" = None

    @property
    def hook(self) -> Any:
        return self.pm.hook

    @property
    def registry(self) -> "ComponentRegistry":
        """Components registered by every plugin (collected on first use)."""
        if self._registry is None:
            from .registry import KINDS, ComponentRegistry

            registry = ComponentRegistry()
            for kind, hook_name in KINDS.items():
                for plugin_name, function in self.implementations(hook_name):
                    self._call_plugin(plugin_name, hook_name, function, register=registry.registrar(kind, plugin_name))
            self._registry = registry
        return self._registry

    @property
    def metrics(self) -> "tuple[Metric, ...]":
        """The metric catalog: the built-in metrics, then every plugin's (collected on first use)."""
        if self._metrics is None:
            from ..metrics.builtin import BUILTIN
            from ..metrics.catalog import CatalogBuilder

            catalog = CatalogBuilder(BUILTIN)
            for plugin_name, function in self.implementations("register_metrics"):
                self._call_plugin(plugin_name, "register_metrics", function, register=catalog.registrar(plugin_name))
            self._metrics = catalog.catalog()
        return self._metrics

    def implementations(self, hook_name: str) -> list[tuple[str, Any]]:
        """(plugin name, function) for ``hook_name`` in pluggy's call order."""
        caller = getattr(self.pm.hook, hook_name)
        return [(self.pm.get_name(impl.plugin) or "?", impl.function) for impl in reversed(caller.get_hookimpls())]

    def _call_plugin(self, plugin_name: str, hook_name: str, function: Any, **kwargs: Any) -> Any:
        if self.trace:
            from ..logs import get_logger

            get_logger(__name__).debug("hook.call", hook=hook_name, plugin=plugin_name)
        try:
            return function(**kwargs)
        except PluginError:
            raise
        except Exception as error:
            raise PluginError(plugin_name, f"hook {hook_name} raised {type(error).__name__}: {error}") from error

    def notify(self, hook_name: str, **kwargs: Any) -> None:
        """Call a lifecycle hook on every plugin; a failure names the plugin that raised."""
        for plugin_name, function in self.implementations(hook_name):
            self._call_plugin(plugin_name, hook_name, function, **kwargs)

    def add_commands(self, cli: Any) -> None:
        """Let every plugin add its CLI commands to ``cli``."""
        for plugin_name, function in self.implementations("register_commands"):
            self._call_plugin(plugin_name, "register_commands", function, cli=cli)

    def describe(self) -> list[dict[str, Any]]:
        """Every plugin with its origin, the hooks it implements and the components it registered."""
        components: dict[str, list[str]] = {}
        for info in self.registry.all():
            components.setdefault(info.plugin, []).append(f"{info.kind}:{info.name}")
        rows = []
        for name, plugin in self.pm.list_name_plugin():
            if plugin is None:
                continue
            origin = self.origins.get(name, PluginOrigin(name, "inline", getattr(plugin, "__name__", repr(plugin))))
            hooks = sorted(caller.name for caller in self.pm.get_hookcallers(plugin) or [])
            rows.append(
                {
                    "name": name,
                    "source": origin.source,
                    "module": origin.module,
                    "distribution": f"{origin.distribution} {origin.version}".strip(),
                    "hooks": hooks,
                    "components": components.get(name, []),
                }
            )
        return rows


def load_plugins(
    extra: Iterable[Any] = (),
    *,
    environ: Mapping[str, str] | None = None,
    builtins: bool = True,
    entry_points: bool = True,
) -> Plugins:
    """Build a fresh plugin manager with the built-in, installed and ``extra`` plugins.

    :param extra: inline plugins (modules, classes or objects with hook implementations), or
        ``(name, plugin)`` pairs; registered last, so their hooks run first.
    :param environ: where to read ``SAFEEMBODAI_*`` variables (default: ``os.environ``).
    """
    env = os.environ if environ is None else environ
    allow = _names(env.get("SAFEEMBODAI_LOAD_PLUGINS"))
    blocked = _names(env.get("SAFEEMBODAI_DISABLE_PLUGINS")) or set()

    pm = pluggy.PluginManager(hookspecs.PROJECT)
    pm.add_hookspecs(hookspecs)
    plugins = Plugins(pm)
    for name in blocked:
        pm.set_blocked(name)

    def wanted(name: str) -> bool:
        return name not in blocked and (allow is None or name in allow)

    found = _entry_points()
    if builtins and not any(_is_builtin(ep) for ep in found):
        raise PluginError(DISTRIBUTION, f"no built-in plugins: the {DISTRIBUTION!r} distribution's entry points "
                                        f"(group {ENTRY_POINT_GROUP!r}) are not installed; install the project as "
                                        "the README says (pip install -e .), again after editing pyproject.toml")
    # the built-ins first, then third parties': a third party cannot take a built-in's name
    for ep in sorted(found, key=lambda ep: not _is_builtin(ep)):
        builtin = _is_builtin(ep)
        if not (builtins if builtin else entry_points) or not wanted(ep.name):
            continue
        if pm.has_plugin(ep.name):
            registered = plugins.origins[ep.name].module
            if registered != ep.value:  # a different package took a registered plugin's name: say so
                raise PluginError(ep.name, f"entry point {ep.value!r} uses the name of the plugin from "
                                           f"{registered!r}; rename the entry point")
            continue
        origin = PluginOrigin(ep.name, "built-in" if builtin else "entry point", ep.value, *_distribution(ep))
        try:
            plugin = ep.load()
        except Exception as error:
            raise PluginError(ep.name, f"failed to load entry point {ep.value!r}: "
                                       f"{type(error).__name__}: {error}") from error
        _register(plugins, ep.name, plugin, origin)
    for item in extra:
        name, plugin = item if isinstance(item, tuple) else (None, item)
        name = name or getattr(plugin, "__name__", None) or type(plugin).__name__
        if wanted(name):
            _register(plugins, name, plugin, PluginOrigin(name, "inline", getattr(plugin, "__module__", "") or name))

    try:
        pm.check_pending()
    except pluggy.PluginValidationError as error:
        plugin_name = pm.get_name(error.plugin) or repr(error.plugin)
        raise PluginError(plugin_name, f"{error} (misspelled hook name? see docs/plugin_hooks.md)") from None

    plugins.trace = bool(env.get("SAFEEMBODAI_TRACE_PLUGINS"))
    return plugins


def _register(plugins: Plugins, name: str, plugin: Any, origin: PluginOrigin) -> None:
    try:
        plugins.pm.register(plugin, name=name)
    except ValueError as error:
        raise PluginError(name, f"could not be registered: {error}") from None
    except pluggy.PluginValidationError as error:
        raise PluginError(name, f"invalid hook implementation: {error}") from None
    plugins.origins[name] = origin
