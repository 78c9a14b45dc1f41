"""guard-mcp as an MCP server: the upstream's tools, listed verbatim, each call through :class:`~.proxy.GuardMcp`.

:func:`build_server` makes the MCP SDK's low-level ``Server`` (so the upstream's tool definitions --
names, descriptions, input and output schemas, annotations -- pass through as the upstream wrote
them, unvalidated and unrewritten). Input is not validated against the schemas here: the readers of
:mod:`.calls` read every call that can actuate, and the upstream validates what it is given. Results
are ``CallToolResult`` objects, so the SDK adds nothing to them.

:func:`serve` runs the whole command: it connects to the robot's rosbridge (guard-mcp's own eyes),
starts the upstream and points it at the configured robot (the policy's ``connect_to_robot`` tool,
when the upstream has one), then serves over stdio, or over streamable HTTP on ``127.0.0.1`` (DNS
rebinding protection on: only ``127.0.0.1`` and ``localhost`` as Host and Origin). SIGHUP resets the
refusals in a row (``stop_only``); SIGTERM and SIGINT end it, a running motion stopped first.
"""

from __future__ import annotations

import signal
import sys
from importlib.metadata import PackageNotFoundError, version
from typing import Any
from urllib.parse import urlsplit

import anyio
from mcp import types
from mcp.server.lowlevel import Server

from ..errors import SafeEmbodAIError
from ..logs import get_logger
from ..ros.robot_file import RobotFile
from .judging import MotionJudge
from .policy import Policy
from .proxy import GuardMcp
from .senses import RobotSenses
from .upstream import Upstream, open_upstream

log = get_logger(__name__)
NAME = "safeembodai-guard-mcp"


def robot_address(url: str) -> tuple[str, int]:
    """``(host, port)`` of a rosbridge URL ``ws://HOST:PORT`` (port 9090 when not given)."""
    parts = urlsplit(url)
    try:
        port = parts.port or 9090
    except ValueError:
        port = 0
    if parts.scheme not in ("ws", "wss") or not parts.hostname or not 0 < port < 65536 or parts.path not in ("", "/"):
        raise SafeEmbodAIError(f"--rosbridge must be ws://HOST:PORT, got {url!r}")
    return parts.hostname, port


def build_server(guard: GuardMcp, upstream: Upstream, instructions: str | None = None) -> Server[Any, Any]:
    """The MCP server: ``upstream``'s tools, calls through ``guard``; ``instructions`` default to the upstream's."""
    try:
        own = version("safeembodai")
    except PackageNotFoundError:  # a source tree that was never installed
        own = None
    server: Server[Any, Any] = Server(NAME, version=own, instructions=instructions or upstream.instructions)
    tools = list(upstream.tools)

    @server.list_tools()
    async def list_tools() -> list[types.Tool]:
        return tools

    @server.call_tool(validate_input=False)
    async def call_tool(name: str, arguments: dict[str, Any]) -> types.CallToolResult:
        return await guard.call(name, arguments)

    return server


async def serve(policy: Policy, robot: RobotFile, guard: Any, *, rosbridge: str, upstream_cmd: str | None,
                upstream_url: str | None, transport: str = "stdio", port: int = 8765) -> None:
    """Run guard-mcp until its client leaves or it is stopped (module docstring)."""
    address = robot_address(rosbridge)
    senses = RobotSenses(robot, scan_timeout_s=policy.scan_timeout_s, odom_topic=policy.odom_topic)
    await anyio.to_thread.run_sync(senses.connect, rosbridge)
    try:
        async with open_upstream(upstream_cmd, upstream_url) as upstream:
            await _point_at_robot(upstream, policy, address)
            guarded = GuardMcp(policy, MotionJudge(guard, robot, policy), senses, upstream.call, address,
                               holonomic=robot.holonomic)
            server = build_server(guarded, upstream)
            with anyio.open_signal_receiver(signal.SIGHUP, signal.SIGTERM, signal.SIGINT) as received:
                await _serve_until_signalled(server, guarded, received, transport, port)
    finally:
        await anyio.to_thread.run_sync(senses.close)


async def _serve_until_signalled(server: Server[Any, Any], guarded: GuardMcp, received: Any, transport: str,
                                 port: int) -> None:
    async with anyio.create_task_group() as tasks:
        tasks.start_soon(_signals, received, guarded, tasks.cancel_scope)
        await _run(server, transport, port)
        tasks.cancel_scope.cancel()


async def _signals(received: Any, guarded: GuardMcp, scope: anyio.CancelScope) -> None:
    """SIGHUP: reset the refusals in a row; SIGTERM, SIGINT: end (a running motion is stopped first)."""
    async for number in received:
        if number == signal.SIGHUP:
            guarded.reset()
        else:
            log.info("guard_mcp.ending", signal=signal.Signals(number).name)
            scope.cancel()


async def _point_at_robot(upstream: Upstream, policy: Policy, address: tuple[str, int]) -> None:
    """Call the upstream's ``connect_to_robot`` (the policy's) with the configured robot, if it has one."""
    listed = {tool.name for tool in upstream.tools}
    tool = next((name for name, kind in policy.tools.items() if kind == "connect_to_robot" and name in listed), None)
    if tool is None:
        return
    result = await upstream.call(tool, {"ip": address[0], "port": address[1]})
    if result.isError:
        text = " ".join(getattr(part, "text", "") for part in result.content)
        raise SafeEmbodAIError(f"the upstream's {tool} towards {address[0]}:{address[1]} failed: {text[:300]}")
    log.info("guard_mcp.upstream_pointed", tool=tool, host=address[0], port=address[1])


async def _run(server: Server[Any, Any], transport: str, port: int) -> None:
    if transport == "stdio":
        from mcp.server.stdio import stdio_server

        async with stdio_server() as (read, write):
            await server.run(read, write, server.create_initialization_options())
        return
    import uvicorn
    from mcp.server.fastmcp.server import StreamableHTTPASGIApp
    from mcp.server.streamable_http_manager import StreamableHTTPSessionManager
    from mcp.server.transport_security import TransportSecuritySettings
    from starlette.applications import Starlette
    from starlette.routing import Route

    security = TransportSecuritySettings(enable_dns_rebinding_protection=True,
                                         allowed_hosts=["127.0.0.1:*", "localhost:*"],
                                         allowed_origins=["http://127.0.0.1:*", "http://localhost:*"])
    manager = StreamableHTTPSessionManager(app=server, security_settings=security)
    app = Starlette(routes=[Route("/mcp", endpoint=StreamableHTTPASGIApp(manager))])
    config = uvicorn.Config(app, host="127.0.0.1", port=port, log_level="warning", lifespan="off")
    print(f"guard-mcp: serving MCP on http://127.0.0.1:{port}/mcp", file=sys.stderr, flush=True)
    async with manager.run():
        await uvicorn.Server(config).serve()
