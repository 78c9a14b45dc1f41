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

#: public name -> the module that defines it (imported on first use, PEP 562; ``hookimpl`` is pluggy's marker,
#: made in ``hookspecs``)
_EXPORTS = {
    "Guard": "api", "GuardReport": "guard_reports", "run_guarded_trial": "api", "AttackSchedule": "attacks",
    "LimitReport": "guard_reports", "TwistReport": "guard_reports",
    "MotionValidator": "held_motion", "MotionVerdict": "held_motion",
    "SlowdownZone": "twist_judging",
    "Attacker": "components", "AttackSurface": "components", "BackendReply": "models.reply",
    "BuildContext": "components", "Environment": "components", "LLMBackend": "components",
    "Perception": "components", "PromptBuilder": "components", "RobotSpec": "robot",
    "StateStore": "components", "Validator": "validation",
    "BackendError": "errors", "ComponentError": "errors", "PluginError": "errors",
    "SafeEmbodAIError": "errors", "ScenarioError": "errors", "StateStoreError": "errors",
    "hookimpl": "hookspecs", "Defences": "loop.defences", "builtin_plugins": "plugins", "load_plugins": "plugins",
    "ValidationContext": "validation",
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
    from .api import Guard, run_guarded_trial  # noqa: F401
    from .attacks import AttackSchedule  # noqa: F401
    from .components import (  # noqa: F401
        Attacker, AttackSurface, BuildContext, Environment, LLMBackend, Perception, PromptBuilder, StateStore,
    )
    from .errors import BackendError, ComponentError, PluginError, SafeEmbodAIError, ScenarioError, StateStoreError  # noqa: F401
    from .guard_reports import GuardReport, LimitReport, TwistReport  # noqa: F401
    from .held_motion import MotionValidator, MotionVerdict  # noqa: F401
    from .hookspecs import hookimpl  # noqa: F401
    from .loop.defences import Defences  # noqa: F401
    from .models.reply import BackendReply  # noqa: F401
    from .plugins import builtin_plugins, load_plugins  # noqa: F401
    from .robot import RobotSpec  # noqa: F401
    from .twist_judging import SlowdownZone  # noqa: F401
    from .validation import ValidationContext, Validator  # noqa: F401
