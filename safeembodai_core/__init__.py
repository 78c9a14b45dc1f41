"""SafeEmbodAI core: contracts, plugin manager, the guarded control loop and the library API.

Importing this package is cheap: no plugin is loaded and no heavy library (pybullet, litellm,
cv2) is imported until a run or a :class:`Guard` asks for one.

* Guard your own robot: :class:`Guard` (see ``docs/library.md``).
* Run the guarded loop around your own parts: :func:`run_guarded_trial`.
* Write a plugin: :mod:`safeembodai_core.hookspecs` and :data:`hookimpl` (see ``docs/plugins.md``);
  test it with :mod:`safeembodai_core.testing`. Every name in ``__all__`` is documented in ``docs/``.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

from .moved_modules import install as _install_moved_modules

_install_moved_modules()  # the previous release's module paths, deprecated (moved_modules.MOVED)

#: public name -> the module that defines it (imported on first use, PEP 562; ``hookimpl`` is pluggy's marker,
#: made in ``hookspecs``)
_EXPORTS = {
    "Guard": "guard.guard", "GuardReport": "guard.reports", "LimitReport": "guard.reports",
    "TwistReport": "guard.reports", "MotionValidator": "guard.held_motion", "MotionVerdict": "guard.held_motion",
    "SlowdownZone": "guard.twist_judging", "run_guarded_trial": "loop.own_parts",
    "AttackSchedule": "contracts.attack_schedule", "RobotSpec": "contracts.robot",
    "Attacker": "contracts.components", "AttackSurface": "contracts.components",
    "BuildContext": "contracts.components", "Environment": "contracts.components",
    "LLMBackend": "contracts.components", "Perception": "contracts.components",
    "PromptBuilder": "contracts.components", "StateStore": "contracts.components",
    "BackendReply": "models.reply", "Validator": "validation.context", "ValidationContext": "validation.context",
    "BackendError": "errors", "ComponentError": "errors", "PluginError": "errors",
    "SafeEmbodAIError": "errors", "ScenarioError": "errors", "StateStoreError": "errors",
    "hookimpl": "hookspecs", "Defences": "loop.defences",
    "builtin_plugins": "plugin.manager", "load_plugins": "plugin.manager",
}

__all__ = sorted(_EXPORTS) + ["__version__"]


def __getattr__(name: str) -> Any:
    if name == "__version__":  # the installed distribution's, so it never drifts from pyproject.toml
        from importlib.metadata import PackageNotFoundError, version

        try:
            return version("safeembodai")
        except PackageNotFoundError:  # imported from a source tree that was never installed
            return "0+unknown"
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'safeembodai_core' has no attribute {name!r}")
    value = getattr(import_module(f".{module}", __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return __all__


if TYPE_CHECKING:  # pragma: no cover
    from .contracts.attack_schedule import AttackSchedule  # noqa: F401
    from .contracts.components import (  # noqa: F401
        Attacker, AttackSurface, BuildContext, Environment, LLMBackend, Perception, PromptBuilder, StateStore,
    )
    from .contracts.robot import RobotSpec  # noqa: F401
    from .errors import BackendError, ComponentError, PluginError, SafeEmbodAIError, ScenarioError, StateStoreError  # noqa: F401
    from .guard.guard import Guard  # noqa: F401
    from .guard.held_motion import MotionValidator, MotionVerdict  # noqa: F401
    from .guard.reports import GuardReport, LimitReport, TwistReport  # noqa: F401
    from .guard.twist_judging import SlowdownZone  # noqa: F401
    from .hookspecs import hookimpl  # noqa: F401
    from .loop.defences import Defences  # noqa: F401
    from .loop.own_parts import run_guarded_trial  # noqa: F401
    from .models.reply import BackendReply  # noqa: F401
    from .plugin.manager import builtin_plugins, load_plugins  # noqa: F401
    from .validation.context import ValidationContext, Validator  # noqa: F401
