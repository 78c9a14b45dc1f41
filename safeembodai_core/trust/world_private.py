"""What only the simulator knows about a world, declared on the options models that could be told it.

A rule's option that describes the world rather than the rule -- the rooms' Labbots' cruising speed,
how close and how far off their heading they see the robot and yield -- is *world-private*: a robot
could not measure it from its own sensors, clock or planner. Its field in the options model carries
``json_schema_extra=WORLD_PRIVATE``::

    cruise_speed_mm_s: float | None = Field(None, ..., json_schema_extra=WORLD_PRIVATE)

An arm that sets such an option is told what only the simulator knows: an oracle, useful for
comparison, not a rule a deployed robot could run as it is. Such an arm says so with ``told: true``
(:class:`~safeembodai_core.loop.defences.Defences`), and ``report.md`` names it and the options under
the arms table. ``tests/core/trust/test_world_private.py`` fails for a shipped scenario whose arm sets one
without saying so. What is and is not marked, and why: ``docs/defences.md`` (``moving_obstacles``).
"""

from __future__ import annotations

from typing import Any

from pydantic import BaseModel

from ..errors import ComponentError

__all__ = ["WORLD_PRIVATE", "private_fields", "told_options", "arms_told"]

#: ``json_schema_extra`` of an options field that only the simulator can know about its world
WORLD_PRIVATE: dict[str, Any] = {"world_private": True}


def private_fields(model: type[BaseModel]) -> frozenset[str]:
    """The fields of an options model declared world-private."""
    return frozenset(name for name, info in model.model_fields.items()
                     if isinstance(extra := info.json_schema_extra, dict) and extra.get("world_private") is True)


def told_options(arm: Any, registry: Any) -> list[str]:
    """``validator.option`` for each world-private option that ``arm``'s validators set (in order).

    Only options the arm's YAML sets count (a default is the rule's own, not a fact it was given); a
    validator whose plugin is not installed says nothing."""
    told = []
    for ref in arm.validators:
        try:
            model = registry.get("validator", ref.use).options
        except ComponentError:  # a missing plugin is reported where the arm is built
            continue
        told += [f"{ref.key}.{name}" for name in sorted(private_fields(model) & set(ref.options))]
    return told


def arms_told(scenario: Any, registry: Any) -> dict[str, list[str]]:
    """Each arm that sets a world-private option, or says it is ``told``: the options it sets."""
    return {name: told_options(arm, registry) for name, arm in scenario.arms.items()
            if arm.told or told_options(arm, registry)}
