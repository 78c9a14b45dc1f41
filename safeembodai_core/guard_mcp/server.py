"""guard-mcp as an MCP server: the upstream's tools, listed verbatim, each call through :class:`~.proxy.GuardMcp`.

:func:`build_server` makes the MCP SDK's low-level ``Server`` (so the upstream's tool definitions --
names, descriptions, input and output schemas, annotations -- pass through as the upstream wrote
them, unvalidated and unrewritten). Input is not validated against the schemas here: the readers of
:mod:`.calls` read every call that can actuate, and the upstream validates what it is given. Results
are ``CallToolResult`` objects, so the SDK adds nothing to them. With ``state_management`` it also
serves one resource of its own, ``safeembodai://state/last`` (R_{i-1}); the upstream's resources and
prompts are not proxied.

:func:`serve` runs the whole command: it connects to the robot's rosbridge (guard-mcp's own eyes),
starts the upstream and points it at the configured robot (the policy's ``connect_to_robot`` tool,
when the upstream has one), opens the session's run folder (:mod:`.session`), then serves, with the
security prefix p before the upstream's instructions (:mod:`.agent`), over stdio, or over streamable
HTTP on ``127.0.0.1`` (DNS rebinding protection on: only ``127.0.0.1`` and ``localhost`` as Host and
Origin). SIGHUP resets the refusals in a row (``stop_only``); SIGTERM and SIGINT end it, a running
motion stopped first; the run folder is finished whatever ends it.
"""

from __future__ import annotations

import json
import signal
import sys
from pathlib import Path
from importlib.metadata import PackageNotFoundError, version
from typing import Any
from urllib.parse import urlsplit

import anyio
from mcp import types
from mcp.server.lowlevel import Server
from mcp.server.lowlevel.helper_types import ReadResourceContents
from mcp.shared.exceptions import McpError
from pydantic import AnyUrl

from ..errors import SafeEmbodAIError
from ..logs import get_logger
from ..ros.robot_file import RobotFile
from .agent import STATE_URI, security_prefix, server_instructions
from .judging import MotionJudge
from .policy import Policy
from .proxy import GuardMcp
from .senses import RobotSenses
from .session import CallSession
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
    """The MCP server: ``upstream``'s tools, calls through ``guard``; ``instructions`` default to the upstream's
    (:func:`serve` gives :func:`~.agent.server_instructions`: p first)."""
    try:
        own = version("safeembodai")
    except PackageNotFoundError:  # a source tree that was never installed
        own = None
    server: Server[Any, Any] = Server(NAME, version=own, instructions=instructions or upstream.instructions)
    tools = list(upstream.tools)
    guard.know_tools(tools)
    state = [types.Resource(uri=AnyUrl(STATE_URI), name="last_executed", title="R_(i-1): the last calls that ran",
                            description="The last calls that ran on the robot through guard-mcp and what they did, "
                                        "the pose now, the refusals in a row (JSON)", mimeType="application/json")]

    @server.list_tools()
    async def list_tools() -> list[types.Tool]:
        return tools

    @server.call_tool(validate_input=False)
    async def call_tool(name: str, arguments: dict[str, Any]) -> types.CallToolResult:
        return await guard.call(name, arguments)

    @server.list_resources()
    async def list_resources() -> list[types.Resource]:
        return state if guard.policy.state_management else []

    @server.read_resource()
    async def read_resource(uri: Any) -> list[ReadResourceContents]:
        if str(uri) != STATE_URI or not guard.policy.state_management:
            raise McpError(types.ErrorData(code=types.INVALID_PARAMS, message=f"no resource {str(uri)[:200]!r}"))
        return [ReadResourceContents(json.dumps(guard.state_now(), indent=1), "application/json")]

    return server


async def serve(policy: Policy, robot: RobotFile, guard: Any, *, rosbridge: str, upstream_cmd: str | None,
                upstream_url: str | None, transport: str = "stdio", port: int = 8765, out: str | Path = "runs",
                plugins: Any = None) -> None:
    """Run guard-mcp until its client leaves or it is stopped (module docstring)."""
    from ..plugin.manager import load_plugins

    address = robot_address(rosbridge)
    plugins = plugins or load_plugins()
    prefix = security_prefix(policy, plugins)  # a variant that does not exist fails before anything starts
    senses = RobotSenses(robot, scan_timeout_s=policy.scan_timeout_s, odom_topic=policy.odom_topic)
    await anyio.to_thread.run_sync(senses.connect, rosbridge)
    try:
        async with open_upstream(upstream_cmd, upstream_url) as upstream:
            await _point_at_robot(upstream, policy, address)
            session = CallSession(policy, plugins, out, rosbridge=rosbridge, upstream=upstream.name)
            guarded = GuardMcp(policy, MotionJudge(guard, robot, policy), senses, upstream.call, address,
                               holonomic=robot.holonomic, on_call=session.record)
            server = build_server(guarded, upstream, server_instructions(policy, prefix, upstream.instructions))
            log.info("guard_mcp.recording", folder=str(session.path))
            ended = ["its client left"]
            try:
                with anyio.open_signal_receiver(signal.SIGHUP, signal.SIGTERM, signal.SIGINT) as received:
                    await _serve_until_signalled(server, guarded, received, transport, port, ended)
            finally:
                with anyio.CancelScope(shield=True):
                    await anyio.to_thread.run_sync(session.finish, guarded, f"guard-mcp ended ({ended[-1]})")
    finally:
        await anyio.to_thread.run_sync(senses.close)


async def _serve_until_signalled(server: Server[Any, Any], guarded: GuardMcp, received: Any, transport: str,
                                 port: int, ended: list[str]) -> None:
    async with anyio.create_task_group() as tasks:
        tasks.start_soon(_signals, received, guarded, tasks.cancel_scope, ended)
        await _run(server, transport, port)
        tasks.cancel_scope.cancel()


async def _signals(received: Any, guarded: GuardMcp, scope: anyio.CancelScope, ended: list[str]) -> None:
    """SIGHUP: reset the refusals in a row; SIGTERM, SIGINT: end (a running motion is stopped first)."""
    async for number in received:
        if number == signal.SIGHUP:
            guarded.reset()
        else:
            ended.append(signal.Signals(number).name)
            log.info("guard_mcp.ending", signal=ended[-1])
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
