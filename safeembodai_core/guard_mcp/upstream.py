"""The MCP server guard-mcp stands in front of, as its client: started over stdio, or reached over HTTP.

:func:`open_upstream` starts ``--upstream-cmd`` as a child process speaking MCP on its stdin and
stdout (its stderr is guard-mcp's; it gets guard-mcp's environment), or connects to ``--upstream-url``
(streamable HTTP), initialises the session and lists every tool (all pages). :class:`Upstream` holds
the tools as the upstream declared them -- guard-mcp lists them verbatim, names, descriptions, input
and output schemas -- and its ``instructions``. :meth:`Upstream.call` never raises: a timeout, an
error answer or a lost connection comes back as a tool error saying so.
"""

from __future__ import annotations

import contextlib
import os
import shlex
import sys
from collections.abc import AsyncIterator
from dataclasses import dataclass
from datetime import timedelta
from typing import Any

from mcp import ClientSession, types

from ..errors import SafeEmbodAIError
from ..logs import get_logger

log = get_logger(__name__)
#: The longest an upstream call may take (ros-mcp's own waits are seconds).
CALL_TIMEOUT_S = 120.0
#: The most tools read from the upstream (pages of tools/list).
MAX_TOOLS = 1000


class UpstreamError(SafeEmbodAIError):
    """The upstream MCP server could not be started, reached or initialised."""


@dataclass
class Upstream:
    """An initialised session with the upstream: its ``tools`` and ``instructions`` (module docstring)."""

    session: ClientSession
    tools: list[types.Tool]
    instructions: str | None
    name: str

    async def call(self, tool: str, arguments: dict[str, Any]) -> types.CallToolResult:
        """The upstream's answer to ``tool(**arguments)``; a failure is a tool error, never an exception."""
        try:
            return await self.session.call_tool(tool, arguments, read_timeout_seconds=timedelta(seconds=CALL_TIMEOUT_S))
        except Exception as error:  # noqa: BLE001 - the agent gets a tool error; guard-mcp serves on
            log.error("guard_mcp.upstream_failed", tool=tool, error=repr(error)[:300])
            text = f"the upstream MCP server {self.name} failed on {tool}: {type(error).__name__}: {error}"[:500]
            return types.CallToolResult(content=[types.TextContent(type="text", text=text)], isError=True)


@contextlib.asynccontextmanager
async def open_upstream(command: str | None = None, url: str | None = None) -> AsyncIterator[Upstream]:
    """The upstream started from ``command`` (a shell-like line: program and arguments, no shell) or at
    ``url``; exactly one of them."""
    if (command is None) == (url is None):
        raise UpstreamError("give the upstream as --upstream-cmd or as --upstream-url, exactly one of them")
    async with contextlib.AsyncExitStack() as stack:
        if command is not None:
            from mcp.client.stdio import StdioServerParameters, stdio_client

            argv = shlex.split(command)
            if not argv:
                raise UpstreamError("--upstream-cmd is empty")
            server = StdioServerParameters(command=argv[0], args=argv[1:], env=dict(os.environ))
            try:
                read, write = await stack.enter_async_context(stdio_client(server, errlog=sys.stderr))
            except OSError as error:
                raise UpstreamError(f"cannot start the upstream {argv[0]}: {error}") from None
            name = argv[0]
        else:
            from mcp.client.streamable_http import streamable_http_client

            assert url is not None
            read, write, _ = await stack.enter_async_context(streamable_http_client(url))
            name = url
        session = await stack.enter_async_context(ClientSession(read, write))
        try:
            initialized = await session.initialize()
            tools: list[types.Tool] = []
            cursor: str | None = None
            while len(tools) < MAX_TOOLS:
                page = await session.list_tools(params=types.PaginatedRequestParams(cursor=cursor))
                tools += page.tools
                cursor = page.nextCursor
                if not cursor:
                    break
        except Exception as error:  # noqa: BLE001 - said once, clearly, at start-up
            raise UpstreamError(f"the upstream MCP server {name} did not start: {type(error).__name__}: "
                                f"{error}") from None
        log.info("guard_mcp.upstream", name=name, tools=len(tools))
        yield Upstream(session, tools[:MAX_TOOLS], initialized.instructions, name)
