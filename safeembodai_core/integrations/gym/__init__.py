"""Gymnasium environments of the paper's rooms, and the SafeEmbodAI guard as a wrapper.

``pip install -e ".[gym]"``, then::

    import gymnasium
    import safeembodai_core.gym  # registers the ids
    from safeembodai_core.gym import SafeEmbodAIGuard

    env = SafeEmbodAIGuard(gymnasium.make("safeembodai/SO-v0", condition="attack"))
    obs, info = env.reset(seed=0)

Ids: ``safeembodai/OF-v0``, ``SO-v0``, ``DO-v0``, ``MO-v0`` (the rooms of ``scenarios/<room>.yaml``)
and ``safeembodai/flatland-v0``. Gymnasium 1.x has no plugin discovery: import this module, or
name it in the id, ``gymnasium.make("safeembodai_core.gym:safeembodai/SO-v0")``
(``safeembodai_core.gym`` is this package's short name). Modules: ``env`` (:class:`SafeEmbodAIEnv`),
``guard`` (:class:`SafeEmbodAIGuard`), ``spaces`` (the spaces and their conversions),
``scenarios`` (each id's scenario). See ``docs/gymnasium.md``.
"""

from __future__ import annotations

try:
    import gymnasium
except ImportError:  # pragma: no cover - depends on the installed extras
    raise ImportError('safeembodai_core.gym needs gymnasium: pip install -e ".[gym]"') from None

from .env import REWARD_COMPLETED, REWARD_PER_METRE, SafeEmbodAIEnv
from .guard import SafeEmbodAIGuard
from .scenarios import ROOMS, default_scenario
from .spaces import Plan

ENV_IDS = tuple(f"safeembodai/{room}-v0" for room in (*ROOMS, "flatland"))


def register_envs() -> None:
    """Register :data:`ENV_IDS` with Gymnasium (done on import; again is harmless)."""
    for env_id, room in zip(ENV_IDS, (*ROOMS, "flatland")):
        if env_id not in gymnasium.registry:
            gymnasium.register(id=env_id, entry_point="safeembodai_core.integrations.gym.env:SafeEmbodAIEnv",
                               kwargs={"room": room})


register_envs()

__all__ = ["ENV_IDS", "REWARD_COMPLETED", "REWARD_PER_METRE", "Plan", "SafeEmbodAIEnv", "SafeEmbodAIGuard",
           "default_scenario", "register_envs"]
