"""``memory``: an in-process state store (per run; nothing survives the process).

Records are deep-copied in and out, so a component that mutates a record it was handed (an
attacker forging the reference state, say) cannot rewrite history; they are kept as
:func:`~safeembodai_core.trust.text.storable` copies, like every store's. Recording a step again
replaces it (the loop writes a planned step before execution and again after). It keeps trial results for
the run's own report, but it is not ``persistent``: an ablation cannot be resumed from it, nor
run with several worker processes (use ``sqlite``).
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict

from safeembodai_core.hookspecs import hookimpl


class MemoryOptions(BaseModel):
    """The ``memory`` store takes no options."""

    model_config = ConfigDict(extra="forbid")


def _factory(options: MemoryOptions, context):
    from .memory_store import MemoryStateStore  # the core's models and numpy only when a store is built

    return MemoryStateStore()


@hookimpl(trylast=True)
def register_state_stores(register):
    register("memory", _factory, options=MemoryOptions,
             description="in-process store; records last as long as the run")
