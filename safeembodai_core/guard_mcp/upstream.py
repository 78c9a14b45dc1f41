"""The MCP server guard-mcp stands in front of, as its client: started over stdio, or reached over HTTP.

:func:`open_upstream` starts ``--upstream-cmd`` as a child process speaking MCP on its stdin and
stdout (its stderr is guard-mcp's; it gets guard-mcp's environment), or connects to ``--upstream-url``
(streamable HTTP), initialises the session and lists every tool (all pages). :class:`Upstream` holds
the tools as the upstream declared them -- guard-mcp lists them verbatim, names, descriptions, input
and output schemas -- and its ``instructions``. :meth:`Upstream.call` never raises: a timeout, an
error answer or a lost connection comes back as a tool error saying so.

The session is the SDK's ``ClientSession`` with one change (:class:`UpstreamSession`): a result is
checked against its tool's output schema by a validator built once per tool, where the SDK checks the
schema itself against its metaschema on every call (1-2 ms of each call, measured by
``bench/guard_mcp_cost.py``). What is checked is the same.
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

from jsonschema.exceptions import SchemaError, best_match  # type: ignore[import-untyped]
from jsonschema.validators import validator_for  # type: ignore[import-untyped]
from mcp import ClientSession, types
from referencing import Registry

from ..errors import SafeEmbodAIError
from ..logs import get_logger

log = get_logger(__name__)
#: The longest an upstream call may take (ros-mcp's own waits are seconds).
CALL_TIMEOUT_S = 120.0
#: The most tools read from the upstream (pages of tools/list).
MAX_TOOLS = 1000


class UpstreamError(SafeEmbodAIError):
    """The upstream MCP server could not be started, reached or initialised."""


class UpstreamSession(ClientSession):
    """The SDK's client session, its results checked by a validator built once per tool (module docstring)."""

    async def _validate_tool_result(self, name: str, result: types.CallToolResult) -> None:
        if name not in self._tool_output_schemas:  # not listed: the SDK lists the tools again, then checks
            return await super()._validate_tool_result(name, result)
        schema = self._tool_output_schemas[name]
        if schema is None:
            return None
        if result.structuredContent is None:
            raise RuntimeError(f"Tool {name} has an output schema but did not return structured content")
        validators = self.__dict__.setdefault("_validators", {})
        if name not in validators:
            kind = validator_for(schema)
            try:
                kind.check_schema(schema)  # once; a bad schema fails every call, as the SDK's check does
            except SchemaError as bad:
                raise RuntimeError(f"Invalid schema for tool {name}: {bad.message}") from None
            validators[name] = kind(schema, registry=Registry())  # $refs within the schema only, as the SDK's
        invalid = best_match(validators[name].iter_errors(result.structuredContent))
        if invalid is not None:
            raise RuntimeError(f"Invalid structured content returned by tool {name}: {invalid.message}")
        return None


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
        session = await stack.enter_async_context(UpstreamSession(read, write))
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
