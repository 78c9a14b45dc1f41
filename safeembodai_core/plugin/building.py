"""Build a scenario's components from its references: the one place a plugin's factory is called.

:class:`ComponentBuilder` is what everything that needs one component of a scenario uses -- the
trial runner (:class:`~safeembodai_core.runs.runner.ScenarioRunner`, for every trial's parts), the
run plan's checks (the backend's preflight and price, whether the store persists), the Inspect
solver's memory store, the warm-up of worker processes -- so none of them builds a whole trial
runner just to call a factory. What is built without a scenario (``Guard``'s rules, Inspect's
provider, the scenario checks' prompt builder) goes through the same call, the registry's ``build_ref``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, Iterable

from ..contracts.components import LLMBackend, StateStore, as_llm_backend
from .manager import Plugins
from .refs import ComponentRef, ref
from ..scenario import Scenario


class ComponentBuilder:
    """Builds components of ``scenario`` with ``plugins``; ``run_dir`` is the folder a component
    may keep files in (a SQLite store's database), None for none."""

    def __init__(self, scenario: Scenario, plugins: Plugins, run_dir: str | Path | None = None) -> None:
        self.scenario, self.plugins = scenario, plugins
        self.run_dir = str(run_dir) if run_dir is not None else None

    def build(self, kind: str, ref: ComponentRef, seed: int = 0, only_to_describe: bool = False) -> Any:
        """Component ``ref`` of ``kind`` (``only_to_describe``: :class:`BuildContext`'s flag); raises
        the registry's error naming the plugin when its options or its factory fail."""
        return self.plugins.registry.build_ref(kind, ref, seed=seed, run_dir=self.run_dir,
                                               only_to_describe=only_to_describe)

    def backend(self, seed: int = 0, only_to_describe: bool = False) -> LLMBackend:
        """The scenario's LLM backend (the caller closes it)."""
        return self.build("llm_backend", self.scenario.backend, seed, only_to_describe)

    def state_store(self, ref: ComponentRef | None = None) -> StateStore:
        """The scenario's state store, or the store ``ref`` names (the caller closes it)."""
        return self.build("state_store", ref or self.scenario.state)

    def environment(self, label: str) -> Any:
        """A new instance of the environment labelled ``label`` (the caller closes it)."""
        return self.build("environment", self.scenario.environment(label))


def build_components(plugins: Plugins, kind: str, items: Iterable[Any], seed: int = 0) -> list[tuple[str, Any]]:
    """Named components from names, options or objects (as the scenario runner builds them: ``label`` is the
    key, ``seed`` the trial's); an object is used as it is, a backend behind its declared adapter."""
    built = []
    for item in items:
        if isinstance(item, (str, dict, ComponentRef)):
            r = ref(item)
            built.append((r.key, plugins.registry.build_ref(kind, r, seed=seed)))
        else:
            built.append((getattr(item, "name", type(item).__name__), as_llm_backend(item) if kind == "llm_backend"
                          else item))
    return built
