"""``outside``: the commands came from a client outside this process, not from an LLM we asked.

The backend a ``safeembodai serve-robot`` session records in its run folder's scenario: a rosbridge
client (an MCP agent, roslibpy, a dashboard, a person) drove the room, so no prompt was built and no
answer parsed here. Reports name it as such; who or what the client was is not recorded, so nothing
says it was, or was not, an LLM. Asked to answer a prompt (an ablation of a scenario naming it), it
fails like an outage: it has nothing to say.
"""

from __future__ import annotations

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.registry import lazy

from .options import OutsideOptions


@hookimpl
def register_llm_backends(register):
    register("outside", lazy(f"{__name__}.backend", "OutsideBackend"), options=OutsideOptions,
             description="commands from a client outside this process (safeembodai serve-robot's record)")
