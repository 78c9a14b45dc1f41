"""The agent's side of MCP: a server started over stdio, its tools listed, calls made and their results read.

:func:`open_tools` starts an MCP server (ros-mcp, or guard-mcp in front of it) as a subprocess and
speaks to it with the official ``mcp`` client: it initialises the session (the server's
``instructions`` are kept: an MCP client hands them to its model), lists the tools and yields a
:class:`McpTools`. Each call is bounded by a deadline and answered as a :class:`ToolOutcome`: the
error flag, the structured content, the text and the images, each as the server sent them (untrusted
data: the readers of :mod:`.readings` and :mod:`.motions` read them strictly).
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, AsyncIterator, Sequence

from ..errors import SafeEmbodAIError

#: The most seconds a tool call may take beyond what it asks to run (a motion's durations).
CALL_SLACK_S = 30.0
#: The most seconds the server may take to start and answer ``initialize``.
START_TIMEOUT_S = 60.0
#: How much of a call's arguments and answer the transcript keeps.
LOGGED_CHARS = 1500
#: Environment for servers built on fastmcp: no update check (no network) and no banner.
QUIET_FASTMCP = {"FASTMCP_CHECK_FOR_UPDATES": "off", "FASTMCP_SHOW_CLI_BANNER": "false"}


@dataclass(frozen=True)
class ToolSpec:
    """A tool as the server lists it: its name, description and input schema (JSON Schema)."""

    name: str
    description: str
    input_schema: dict[str, Any]


@dataclass(frozen=True)
class ToolOutcome:
    """A call's result: ``error`` (the server's ``isError``, or the call failed here), ``structured``
    (its structured content, a dict, or None), ``text`` (its text parts joined) and ``images``
    (``(mime type, bytes)`` of its image parts)."""

    tool: str
    error: bool
    structured: dict[str, Any] | None = None
    text: str = ""
    images: tuple[tuple[str, bytes], ...] = ()

    @property
    def content(self) -> Any:
        """The structured content, else the text read as JSON when it is JSON, else the text."""
        if self.structured is not None:
            return self.structured
        from ..models.strict_json import ResponseParseError, read_json_document

        try:  # the server's text is outside bytes: the one strict JSON reader, or it stays text
            return read_json_document(self.text, "a tool's text")
        except ResponseParseError:
            return self.text


def outcome_of(tool: str, result: Any) -> ToolOutcome:
    """A ``CallToolResult`` as a :class:`ToolOutcome` (an image whose data is not base64 is left out)."""
    texts, images = [], []
    for part in getattr(result, "content", None) or []:
        kind = getattr(part, "type", None)
        if kind == "text":
            texts.append(str(getattr(part, "text", "")))
        elif kind == "image":
            try:
                images.append((str(getattr(part, "mimeType", "")), base64.b64decode(getattr(part, "data", ""),
                                                                                     validate=True)))
            except (ValueError, TypeError):
                continue
    structured = getattr(result, "structuredContent", None)
    return ToolOutcome(tool, bool(getattr(result, "isError", False)),
                       structured if isinstance(structured, dict) else None, "\n".join(texts), tuple(images))


@dataclass
class McpTools:
    """An initialised MCP session: the server's ``instructions``, its ``tools`` and :meth:`call`."""

    session: Any
    instructions: str | None
    tools: list[ToolSpec] = field(default_factory=list)
    #: every call so far: ``{"tool", "arguments", "error", "answer", "seconds"}`` (arguments and answer cut
    #: to :data:`LOGGED_CHARS`), the trial's transcript
    log: list[dict[str, Any]] = field(default_factory=list)

    def has(self, name: str) -> bool:
        return any(tool.name == name for tool in self.tools)

    async def call(self, tool: str, arguments: dict[str, Any], runs_s: float = 0.0) -> ToolOutcome:
        """Call ``tool``; a call that takes more than ``runs_s`` + :data:`CALL_SLACK_S` seconds, or that
        the session fails, is an error outcome saying so (the loop goes on: the robot's base stops on
        its own timeout)."""
        started = time.monotonic()
        try:
            result = await asyncio.wait_for(self.session.call_tool(tool, arguments), runs_s + CALL_SLACK_S)
            outcome = outcome_of(tool, result)
        except asyncio.TimeoutError:
            outcome = ToolOutcome(tool, True, text=f"no answer within {runs_s + CALL_SLACK_S:g} s")
        except Exception as error:  # the client refuses a malformed result, the server died: the call failed
            outcome = ToolOutcome(tool, True, text=f"the call failed: {type(error).__name__}: {error}"[:500])
        answer = outcome.text if outcome.structured is None else json.dumps(outcome.structured, default=str)
        self.log.append({"tool": tool, "arguments": json.dumps(arguments, default=str)[:LOGGED_CHARS],
                         "error": outcome.error, "answer": answer[:LOGGED_CHARS],
                         "images": len(outcome.images), "seconds": round(time.monotonic() - started, 3)})
        return outcome


def tool_specs(listed: Sequence[Any]) -> list[ToolSpec]:
    """The listed tools as :class:`ToolSpec`."""
    return [ToolSpec(str(tool.name), str(tool.description or ""), dict(tool.inputSchema or {})) for tool in listed]


async def connected(session: Any, name: str = "the MCP server") -> McpTools:
    """``session`` (an open ``mcp.ClientSession``) initialised, its instructions kept and its tools listed."""
    try:
        initialised = await asyncio.wait_for(session.initialize(), START_TIMEOUT_S)
        listed = await asyncio.wait_for(session.list_tools(), START_TIMEOUT_S)
    except asyncio.TimeoutError:
        raise SafeEmbodAIError(f"{name} did not start within {START_TIMEOUT_S:g} s") from None
    return McpTools(session, initialised.instructions, tool_specs(listed.tools))


@contextlib.asynccontextmanager
async def open_tools(command: Sequence[str], *, cwd: str | Path | None = None, errlog: Path | None = None,
                     environment: dict[str, str] | None = None) -> AsyncIterator[McpTools]:
    """The MCP server ``command`` over stdio (its stderr to ``errlog``), initialised and its tools listed."""
    try:
        import mcp
        from mcp.client.stdio import StdioServerParameters, get_default_environment, stdio_client
    except ImportError:
        raise SafeEmbodAIError("the MCP agent needs the MCP SDK: pip install -e \".[mcp]\"") from None
    env = {**get_default_environment(), **QUIET_FASTMCP, **(environment or {})}
    if "PYTHONPATH" in os.environ and "PYTHONPATH" not in env:
        env["PYTHONPATH"] = os.environ["PYTHONPATH"]
    server = StdioServerParameters(command=command[0], args=list(command[1:]), env=env,
                                   cwd=str(cwd) if cwd is not None else None)
    with contextlib.ExitStack() as files:
        log = files.enter_context(open(errlog, "a", encoding="utf-8")) if errlog is not None else None
        async with stdio_client(server, **({"errlog": log} if log is not None else {})) as (read, write):
            async with mcp.ClientSession(read, write) as session:
                yield await connected(session, f"the MCP server {command[0]}")
