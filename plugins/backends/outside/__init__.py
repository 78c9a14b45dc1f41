"""``outside``: the commands came from a client outside this process, not from an LLM we asked.

The backend a ``safeembodai serve-robot`` session records in its run folder's scenario: a rosbridge
client (an MCP agent, roslibpy, a dashboard, a person) drove the room, so no prompt was built and no
answer parsed here. Reports name it as such; who or what the client was is not recorded, so nothing
says it was, or was not, an LLM. Asked to answer a prompt (an ablation of a scenario naming it), it
fails like an outage: it has nothing to say.
"""

from __future__ import annotations

from safeembodai_core.components import LLMBackend
from safeembodai_core.descriptions import BackendDescription, BackendOptions
from safeembodai_core.errors import BackendError
from safeembodai_core.hookspecs import hookimpl


class OutsideOptions(BackendOptions):
    """No options: the client is outside."""

    def describe(self) -> BackendDescription:
        return BackendDescription(model="an outside client over rosbridge (who or what it was is not recorded)",
                                  model_source="safeembodai serve-robot: commands received, no prompt sent")


class OutsideBackend(LLMBackend):
    """Answers nothing: the commands of a served room come over the wire (module docstring)."""

    def __init__(self, options: OutsideOptions) -> None:
        self.options = options

    def complete(self, prompt, rng):
        raise BackendError("backend 'outside': the commands of a served room came from a client outside this "
                           "process; it cannot answer a prompt (choose an LLM backend to run this scenario)")


@hookimpl
def register_llm_backends(register):
    register("outside", lambda options, context: OutsideBackend(options), options=OutsideOptions,
             description="commands from a client outside this process (safeembodai serve-robot's record)")
