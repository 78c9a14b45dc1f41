"""Module paths of the previous release, kept importable for one release (deprecated).

The core's loose modules moved into subpackages that name the architecture (``docs/architecture.md``,
"Where things live"). A third-party plugin should import only the public paths ``docs/plugins.md``
lists (``safeembodai_core``'s ``__all__``, ``safeembodai_core.models``, ``safeembodai_core.testing``,
``safeembodai_core.hookspecs``, ``safeembodai_core.logs``), none of which moved. One that imported an
old path anyway still loads: importing a path of :data:`MOVED` warns (``DeprecationWarning``, naming
the new path) and gives the module at its new path, the same module object, so classes and
``isinstance`` agree. The project's own code imports none of these paths (``tests/meta``).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import sys
import types
import warnings

#: old module path -> where it lives now (for one release). ``safeembodai_core.validation`` became a package that
#: keeps its names; ``safeembodai_core.trust`` became the trust boundary's package (its inventory: ``trust.inventory``).
MOVED: dict[str, str] = {
    "safeembodai_core.api": "safeembodai_core.guard.guard",
    "safeembodai_core.guard_reports": "safeembodai_core.guard.reports",
    "safeembodai_core.twist_judging": "safeembodai_core.guard.twist_judging",
    "safeembodai_core.held_motion": "safeembodai_core.guard.held_motion",
    "safeembodai_core.ros.command_filter": "safeembodai_core.guard.command_filter",
    "safeembodai_core.ros.bag_guard": "safeembodai_core.guard.bag_guard",
    "safeembodai_core.text_safety": "safeembodai_core.trust.text",
    "safeembodai_core.quoting": "safeembodai_core.trust.quoting",
    "safeembodai_core.redaction": "safeembodai_core.trust.redaction",
    "safeembodai_core.world_private": "safeembodai_core.trust.world_private",
    "safeembodai_core.runner": "safeembodai_core.runs.runner",
    "safeembodai_core.trial_artefacts": "safeembodai_core.runs.artefacts",
    "safeembodai_core.trial_files": "safeembodai_core.runs.trial_files",
    "safeembodai_core.run_files": "safeembodai_core.runs.files",
    "safeembodai_core.ablation.run_folder": "safeembodai_core.runs.folder",
    "safeembodai_core.rerun_export": "safeembodai_core.runs.rerun_recording",
    "safeembodai_core.trial_words": "safeembodai_core.report.words",
    "safeembodai_core.report.captions": "safeembodai_core.runs.captions",
    "safeembodai_core.plugins": "safeembodai_core.plugin.manager",
    "safeembodai_core.registry": "safeembodai_core.plugin.registry",
    "safeembodai_core.refs": "safeembodai_core.plugin.refs",
    "safeembodai_core.building": "safeembodai_core.plugin.building",
    "safeembodai_core.components": "safeembodai_core.contracts.components",
    "safeembodai_core.descriptions": "safeembodai_core.contracts.descriptions",
    "safeembodai_core.robot": "safeembodai_core.contracts.robot",
    "safeembodai_core.attacks": "safeembodai_core.contracts.attack_schedule",
}


class _MovedModuleFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Answers an old path of :data:`MOVED` with the module at its new path (last on ``sys.meta_path``:
    a real module of the old name, were one ever added back, wins)."""

    def find_spec(self, fullname: str, path: object = None,
                  target: types.ModuleType | None = None) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED:
            return None
        return importlib.machinery.ModuleSpec(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        return types.ModuleType(spec.name)  # a placeholder: exec_module puts the real module in its place

    def exec_module(self, module: types.ModuleType) -> None:
        new = MOVED[module.__name__]
        warnings.warn(f"{module.__name__} moved to {new}; the old path goes in the next release "
                      "(docs/plugins.md lists the public paths)", DeprecationWarning, stacklevel=2)
        # the import system hands back whatever sys.modules holds under the name once this returns
        sys.modules[module.__name__] = importlib.import_module(new)


def install() -> None:
    """Put the finder on ``sys.meta_path`` once (``safeembodai_core/__init__`` does, on import)."""
    if not any(isinstance(finder, _MovedModuleFinder) for finder in sys.meta_path):
        sys.meta_path.append(_MovedModuleFinder())
