"""Named components: what plugins register and scenarios select by name.

Each kind of component has its own registry hook (``register_validators`` ...). The registry
records which plugin registered each name, rejects a second registration of the same name
(naming both plugins), checks that options models forbid unknown keys, and builds components
from raw options with errors that name the component and the key at fault.
"""

from __future__ import annotations

import difflib
from dataclasses import dataclass
from importlib import import_module
from typing import TYPE_CHECKING, Any, Callable

from pydantic import BaseModel, ConfigDict, ValidationError

from ..errors import ComponentError, PluginError, SafeEmbodAIError

if TYPE_CHECKING:
    from ..contracts.components import BuildContext
    from ..hookspecs import Register
    from .refs import ComponentRef

#: component kind -> registry hook name
KINDS: dict[str, str] = {
    "environment": "register_environments",
    "perception": "register_perceptions",
    "prompt_builder": "register_prompt_builders",
    "state_store": "register_state_stores",
    "validator": "register_validators",
    "attacker": "register_attackers",
    "llm_backend": "register_llm_backends",
}


class NoOptions(BaseModel):
    """Options model for components that take none."""

    model_config = ConfigDict(extra="forbid")


@dataclass(frozen=True)
class ComponentInfo:
    """A registered component: its kind, name, owning plugin, factory and options model."""

    kind: str
    name: str
    plugin: str
    factory: Callable[[Any, "BuildContext"], Any]
    options: type[BaseModel]
    description: str = ""


def lazy(module: str, attribute: str, *args: Any) -> Callable[[Any, "BuildContext"], Any]:
    """A factory that imports ``attribute`` from ``module`` only when a component is built, and
    returns ``attribute(*args, options)``.

    For a plugin whose registration module must stay light (the implementation imports numpy,
    pybullet, rich ...): ``register("lidar_clearance", lazy(f"{__name__}.rules",
    "LidarClearanceRule"), options=...)`` is ``from .rules import LidarClearanceRule`` inside a
    factory that returns ``LidarClearanceRule(options)``, failing the same way (``ImportError``).
    """

    def factory(options: Any, context: "BuildContext") -> Any:
        imported = import_module(module)
        try:
            built = getattr(imported, attribute)
        except AttributeError:
            where = getattr(imported, "__file__", None) or "unknown location"
            raise ImportError(f"cannot import name {attribute!r} from {module!r} ({where})", name=module) from None
        return built(*args, options)

    factory.__name__ = factory.__qualname__ = f"build_{attribute}"
    return factory


class ComponentOptionsError(ComponentError):
    """Options for a component failed validation; ``errors`` holds (location, message) pairs."""

    def __init__(self, kind: str, name: str, errors: list[tuple[tuple[Any, ...], str]]):
        self.kind, self.name, self.errors = kind, name, errors
        detail = "; ".join(f"{'.'.join(map(str, loc)) or '(options)'}: {msg}" for loc, msg in errors)
        super().__init__(f"{kind} {name!r}: invalid options: {detail}")


class ComponentRegistry:
    """All components of one run, by kind and name."""

    def __init__(self) -> None:
        self._items: dict[tuple[str, str], ComponentInfo] = {}

    def registrar(self, kind: str, plugin: str) -> Register:
        """The ``register`` callable handed to ``plugin``'s registry hook for ``kind``."""

        def register(
            name: str,
            factory: Callable[[Any, "BuildContext"], Any],
            *,
            options: type[BaseModel] = NoOptions,
            description: str = "",
        ) -> None:
            self.add(ComponentInfo(kind, name, plugin, factory, options, description))

        return register

    def add(self, info: ComponentInfo) -> None:
        if not isinstance(info.name, str) or not info.name.strip():
            raise PluginError(info.plugin, f"registered a {info.kind} with an empty or non-string name")
        if not callable(info.factory):
            raise PluginError(info.plugin, f"{info.kind} {info.name!r}: factory is not callable")
        if not (isinstance(info.options, type) and issubclass(info.options, BaseModel)):
            raise PluginError(info.plugin, f"{info.kind} {info.name!r}: options must be a pydantic model class")
        if info.options.model_config.get("extra") != "forbid":
            raise PluginError(
                info.plugin,
                f"{info.kind} {info.name!r}: options model {info.options.__name__} must set "
                "model_config = ConfigDict(extra='forbid') so unknown keys are rejected",
            )
        existing = self._items.get((info.kind, info.name))
        if existing is not None:
            raise PluginError(
                info.plugin,
                f"{info.kind} {info.name!r} is already registered by plugin {existing.plugin!r}; "
                "two plugins cannot register the same name (block one with SAFEEMBODAI_DISABLE_PLUGINS)",
            )
        self._items[(info.kind, info.name)] = info

    def names(self, kind: str) -> list[str]:
        return sorted(name for k, name in self._items if k == kind)

    def all(self) -> list[ComponentInfo]:
        return sorted(self._items.values(), key=lambda i: (i.kind, i.name))

    def get(self, kind: str, name: str) -> ComponentInfo:
        if kind not in KINDS:
            raise ComponentError(f"unknown component kind {kind!r}; kinds are {', '.join(KINDS)}")
        info = self._items.get((kind, name))
        if info is None:
            known = self.names(kind)
            close = difflib.get_close_matches(str(name), known, n=1)
            hint = f" Did you mean {close[0]!r}?" if close else ""
            listing = ", ".join(known) if known else "none (is the plugin installed and not disabled?)"
            raise ComponentError(f"no {kind.replace('_', ' ')} named {name!r}.{hint} Registered: {listing}")
        return info

    def validate_options(self, kind: str, name: str, raw: dict[str, Any] | BaseModel | None) -> BaseModel:
        info = self.get(kind, name)
        if isinstance(raw, info.options):
            return raw
        try:
            return info.options.model_validate(raw or {})
        except ValidationError as error:
            raise ComponentOptionsError(
                kind, name, [(tuple(e["loc"]), e["msg"]) for e in error.errors()]
            ) from None

    def build_ref(self, kind: str, ref: "ComponentRef", *, seed: int = 0, run_dir: str | None = None,
                  only_to_describe: bool = False) -> Any:
        """Component ``ref`` of ``kind``, its factory told who builds it (:class:`BuildContext`: the ref's
        key as ``label``, ``seed``, ``run_dir``, ``only_to_describe``). How the core builds every part:
        a scenario's (:class:`~safeembodai_core.plugin.building.ComponentBuilder`), ``Guard``'s rules, Inspect's
        provider, the scenario checks' prompt builder."""
        from ..contracts.components import BuildContext

        context = BuildContext(component=ref.use, kind=kind, seed=seed, run_dir=run_dir, label=ref.key,
                               only_to_describe=only_to_describe)
        return self.build(kind, ref.use, ref.options, context)

    def build(self, kind: str, name: str, raw_options: Any = None, context: "BuildContext | None" = None) -> Any:
        """Validate options and call the factory; a factory that raises is reported by plugin name."""
        info = self.get(kind, name)
        options = self.validate_options(kind, name, raw_options)
        if context is None:
            from ..contracts.components import BuildContext

            context = BuildContext(component=name, kind=kind)
        try:
            built = info.factory(options, context)
            if kind == "llm_backend":  # every optional method declared (the core calls them, no getattr)
                from ..contracts.components import as_llm_backend

                built = as_llm_backend(built)
            elif kind == "environment":  # likewise: OPTIONAL_ENVIRONMENT_METHODS, declared
                from ..contracts.components import as_environment

                built = as_environment(built)
            return built
        except SafeEmbodAIError:  # a reported, user-facing problem (a locked database, a missing file)
            raise
        except Exception as error:  # a plugin bug: name the plugin, keep the cause for --debug
            raise PluginError(info.plugin,
                              f"building {kind} {name!r} failed: {type(error).__name__}: {error}") from error
