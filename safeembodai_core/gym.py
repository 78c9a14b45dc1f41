"""``import safeembodai_core.gym`` registers the Gymnasium ids ``safeembodai/<room>-v0``.

The integration lives in :mod:`safeembodai_core.integrations.gym` (next to the Inspect AI one);
this module is its short name, re-exporting it. Needs ``pip install -e ".[gym]"``; see ``docs/gymnasium.md``.
"""

from .integrations.gym import (  # noqa: F401
    ENV_IDS,
    REWARD_COMPLETED,
    REWARD_PER_METRE,
    Plan,
    SafeEmbodAIEnv,
    SafeEmbodAIGuard,
    __all__,
    default_scenario,
    register_envs,
)
