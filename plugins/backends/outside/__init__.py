"""``outside``: the commands came from a client outside this process, not from an LLM we asked.

The backend a ``safeembodai serve-robot`` session records in its run folder's scenario: a rosbridge
client (an MCP agent, roslibpy, a dashboard, a person) drove the room, so no prompt was built and no
answer parsed here. Reports name it as such; who or what the client was is not recorded, so nothing
says it was, or was not, an LLM. Asked to answer a prompt (an ablation of a scenario naming it), it
fails like an outage: it has nothing to say. ``client: mcp`` names the client of a ``safeembodai
guard-mcp`` session: an MCP agent's tool calls, judged there.

The environment ``outside`` is the robot of a guard-mcp session: a robot reached over rosbridge,
outside this process, whose calls are recorded and which is never simulated here (building it fails
with that said, so a replay of such a session says why it cannot be made).
"""

from __future__ import annotations

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy

from .options import OutsideOptions, OutsideRobotOptions


@hookimpl
def register_llm_backends(register):
    register("outside", lazy(f"{__name__}.backend", "OutsideBackend"), options=OutsideOptions,
             description="commands from a client outside this process (safeembodai serve-robot's and guard-mcp's "
                         "records)")


@hookimpl
def register_environments(register):
    register("outside", lazy(f"{__name__}.backend", "OutsideRobot"), options=OutsideRobotOptions,
             description="a robot outside this process, reached over rosbridge (safeembodai guard-mcp's record); "
                         "never simulated")
