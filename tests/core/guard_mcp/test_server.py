"""guard-mcp's MCP server in process, reached by the official MCP client: tools listed verbatim, calls guarded."""

from __future__ import annotations

import asyncio
import json

import pytest

pytest.importorskip("mcp", reason="guard-mcp needs the MCP SDK: pip install -e '.[mcp]'")
from mcp import types  # noqa: E402
from mcp.shared.memory import create_connected_server_and_client_session  # noqa: E402

from mcp.shared.exceptions import McpError  # noqa: E402

from safeembodai_core.errors import SafeEmbodAIError  # noqa: E402
from safeembodai_core.guard_mcp.agent import STATE_URI  # noqa: E402
from safeembodai_core.guard_mcp.server import build_server, robot_address  # noqa: E402
from safeembodai_core.guard_mcp.upstream import Upstream  # noqa: E402

#: two of ros-mcp 3.1.2's tools as it lists them: an output schema the client checks, and annotations
TOOLS = [
    types.Tool(name="publish_for_durations", title=None, description="Publish a sequence of messages ...",
               inputSchema={"properties": {"topic": {"default": "", "type": "string"},
                                           "msg_type": {"default": "", "type": "string"},
                                           "messages": {"default": [], "items": {"additionalProperties": True,
                                                                                 "type": "object"}, "type": "array"},
                                           "durations": {"default": [], "items": {"type": "number"},
                                                         "type": "array"},
                                           "rate_hz": {"default": 0, "type": "number"}}, "type": "object"},
               outputSchema={"additionalProperties": True, "type": "object"},
               annotations=types.ToolAnnotations(title="Publish for Durations", destructiveHint=True),
               _meta={"_fastmcp": {"tags": []}}),
    types.Tool(name="get_topics", description="Get topics", inputSchema={"properties": {}, "type": "object"},
               outputSchema={"additionalProperties": True, "type": "object"},
               annotations=types.ToolAnnotations(title="Get Topics", readOnlyHint=True)),
]


def test_the_upstreams_tools_are_listed_verbatim_and_calls_are_guarded(rig, scans):
    r = rig()
    r.see(scans.open())
    server = build_server(r.mcp, Upstream(None, TOOLS, "the upstream's own instructions", "fake"))  # type: ignore[arg-type]

    async def session():
        async with create_connected_server_and_client_session(server) as client:
            listed = await client.list_tools()
            safe = await client.call_tool("publish_for_durations", {
                "topic": "/cmd_vel", "msg_type": "geometry_msgs/msg/Twist", "messages": [scans.twist(0.2)],
                "durations": [0.4]})
            into_nothing = await client.call_tool("publish_for_durations", {
                "topic": "/cmd_vel", "msg_type": "geometry_msgs/msg/Twist", "messages": [scans.twist(9.0)],
                "durations": [0.4]})
            unknown = await client.call_tool("format_disk", {})
            return listed, safe, into_nothing, unknown

    listed, safe, into_nothing, unknown = asyncio.run(session())
    assert [tool.model_dump() for tool in listed.tools] == [tool.model_dump() for tool in TOOLS]
    assert not safe.isError and safe.structuredContent["guard"]["verdict"] == "forwarded"
    refusal = json.loads(into_nothing.content[0].text)
    assert into_nothing.isError and refusal == into_nothing.structuredContent
    assert "max_velocity" in " ".join(refusal["reasons"]) and refusal["safe"]["slow_to_m_s"] == 0.5
    assert unknown.isError and "maps no such tool" in unknown.content[0].text


def test_the_instructions_are_the_upstreams_unless_given(rig):
    server = build_server(rig().mcp, Upstream(None, TOOLS, "upstream says", "fake"))  # type: ignore[arg-type]
    assert server.create_initialization_options().instructions == "upstream says"
    server = build_server(rig().mcp, Upstream(None, TOOLS, "upstream says", "fake"), "p, then upstream says")  # type: ignore[arg-type]
    assert server.create_initialization_options().instructions == "p, then upstream says"


def test_the_last_executed_calls_are_a_resource_the_client_reads(rig, scans):
    r = rig()
    r.see(scans.open())
    server = build_server(r.mcp, Upstream(None, TOOLS, None, "fake"))  # type: ignore[arg-type]

    async def session():
        async with create_connected_server_and_client_session(server) as client:
            before = await client.read_resource(STATE_URI)
            await client.call_tool("publish_for_durations", {"topic": "/cmd_vel", "msg_type": "geometry_msgs/msg/Twist",
                                                             "messages": [scans.twist(0.1)], "durations": [0.2]})
            listed = await client.list_resources()
            after = await client.read_resource(STATE_URI)
            with pytest.raises(McpError, match="no resource"):
                await client.read_resource("safeembodai://state/other")
            return before, listed, after

    before, listed, after = asyncio.run(session())
    assert [str(resource.uri) for resource in listed.resources] == [STATE_URI]
    assert json.loads(before.contents[0].text)["last_executed"] == []
    state = json.loads(after.contents[0].text)
    assert after.contents[0].mimeType == "application/json" and state["refusals_in_a_row"] == 0
    assert [entry["verdict"] for entry in state["last_executed"]] == ["forwarded"]


def test_without_state_management_there_is_no_resource(rig):
    server = build_server(rig(state_management=False).mcp, Upstream(None, TOOLS, None, "fake"))  # type: ignore[arg-type]

    async def session():
        async with create_connected_server_and_client_session(server) as client:
            return await client.list_resources()

    assert asyncio.run(session()).resources == []


@pytest.mark.parametrize("url, address", [("ws://127.0.0.1:9090", ("127.0.0.1", 9090)),
                                          ("ws://robot.local", ("robot.local", 9090))])
def test_the_robots_address_comes_from_the_rosbridge_url(url, address):
    assert robot_address(url) == address


@pytest.mark.parametrize("url", ["http://127.0.0.1:9090", "ws://:9090", "ws://host:99999", "ws://host:9090/x",
                                 "127.0.0.1:9090"])
def test_a_rosbridge_url_that_is_not_one_is_refused(url):
    with pytest.raises(SafeEmbodAIError, match="ws://HOST:PORT"):
        robot_address(url)
