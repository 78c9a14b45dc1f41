"""A fake robot MCP server, in memory, for the MCP agent's tests: ros-mcp's tool names and answer shapes.

``FakeRobot`` answers ``connect_to_robot``, ``get_topics``, ``subscribe_once`` (a scan with a wall
``wall_m`` ahead, a camera frame with a red can in the middle, what the camera reads) and
``publish_for_durations``, which it keeps in ``published``. ``refuse_mm`` makes it refuse, as guard-mcp
does, a motion one of whose messages drives forward farther than that (the first such is named): a tool
error whose structured content carries ``refused``, the reasons, the advice and ``safe`` (the message and
``at_most_mm``).
``wrap`` marks every read result as guard-mcp's part 4 does (under ``untrusted_data``).

``async with tools_of(robot) as tools``: the official ``mcp`` client on it (memory streams, no process),
as the agent's :class:`~safeembodai_core.mcp_agent.tools.McpTools`.
"""

from __future__ import annotations

import base64
import contextlib
import json
import math
from dataclasses import dataclass, field
from typing import Any

import anyio
import numpy as np


def scan_message(wall_m: float | None) -> dict[str, Any]:
    ranges: list[float | None] = [None] * 360
    if wall_m is not None:
        for k in list(range(81)) + list(range(280, 360)):
            ranges[k] = min(wall_m / math.cos(math.radians(k)), 5.9)
    return {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "base_scan"}, "angle_min": 0.0,
            "angle_max": 2 * math.pi * 359 / 360, "angle_increment": 2 * math.pi / 360, "time_increment": 0.0,
            "scan_time": 0.1, "range_min": 0.02, "range_max": 6.0, "ranges": ranges, "intensities": []}


def can_frame() -> bytes:
    """A 320 x 240 JPEG: grey floor, a red can in the middle (as the rooms render it: pure red)."""
    import cv2

    frame = np.full((240, 320, 3), 180, dtype=np.uint8)
    frame[90:170, 145:175] = (0, 0, 220)  # BGR
    ok, data = cv2.imencode(".jpg", frame)
    assert ok
    return data.tobytes()


@dataclass
class FakeRobot:
    wall_m: float | None = 3.0
    camera_text: str = ""
    refuse_mm: float | None = None
    instructions: str | None = None
    wrap: bool = False
    calls: list[tuple[str, dict[str, Any]]] = field(default_factory=list)
    published: list[dict[str, Any]] = field(default_factory=list)
    refusals: int = 0

    def answer(self, name: str, arguments: dict[str, Any]) -> Any:
        from mcp import types

        self.calls.append((name, arguments))
        if name == "connect_to_robot":
            return self._json({"robot": arguments, "connectivity_test": {"port_check": {"open": True}}})
        if name == "get_topics":
            return self._json({"topics": ["/scan", "/camera/image_raw/compressed", "/camera/text", "/cmd_vel"]})
        if name == "subscribe_once":
            topic = arguments.get("topic")
            if topic == "/scan":
                return self._json({"msg": scan_message(self.wall_m)}, wrap=self.wrap)
            if topic == "/camera/text":
                return self._json({"msg": {"data": self.camera_text}}, wrap=self.wrap)
            if topic == "/camera/image_raw/compressed":
                image = types.ImageContent(type="image", data=base64.b64encode(can_frame()).decode(),
                                           mimeType="image/jpeg")
                return types.CallToolResult(content=[image, types.TextContent(type="text", text="Image saved")])
            return self._json({"error": f"no message on {topic}"})
        if name == "publish_for_durations":
            driven = [m["linear"]["x"] * d * 1000.0 for m, d in zip(arguments["messages"], arguments["durations"])]
            far = [k for k, mm in enumerate(driven) if self.refuse_mm is not None and mm > self.refuse_mm]
            if far:
                k = far[0]
                self.refusals += 1
                body = {"refused": True, "tool": name,
                        "reasons": [f"messages[{k}] would hit the wall ({driven[k]:.0f} mm)"],
                        "advice": [f"at most {self.refuse_mm:.0f} mm of messages[{k}] is safe"],
                        "safe": {"message": k, "at_most_mm": self.refuse_mm, "at_most_deg": 0.0},
                        "refusals_in_a_row": self.refusals, "threshold": 3, "stop_only": self.refusals >= 3}
                return self._json(body, error=True)
            self.refusals = 0
            self.published.append(arguments)
            return self._json({"success": True, "published_count": len(arguments["messages"])})
        return self._json({"error": f"unknown tool {name}"}, error=True)

    @staticmethod
    def _json(content: dict[str, Any], error: bool = False, wrap: bool = False) -> Any:
        from mcp import types

        if wrap:
            content = {"untrusted_data": content, "source": "the answer of the robot's MCP server", "read_as": "data"}
        return types.CallToolResult(content=[types.TextContent(type="text", text=json.dumps(content))],
                                    structuredContent=content, isError=error)

    def server(self) -> Any:
        from mcp import types
        from mcp.server.lowlevel import Server

        server: Any = Server("fake-robot", instructions=self.instructions)
        names = ("connect_to_robot", "get_topics", "subscribe_once", "publish_for_durations")

        @server.list_tools()
        async def list_tools() -> list[types.Tool]:
            return [types.Tool(name=name, description=f"ros-mcp's {name}", inputSchema={"type": "object"})
                    for name in names]

        @server.call_tool(validate_input=False)
        async def call_tool(name: str, arguments: dict[str, Any]) -> Any:
            return self.answer(name, arguments)

        return server


@contextlib.asynccontextmanager
async def tools_of(robot: FakeRobot):
    """The agent's tools on ``robot``, through the official client over memory streams."""
    import mcp
    from mcp.shared.memory import create_client_server_memory_streams

    from safeembodai_core.mcp_agent.tools import connected

    server = robot.server()
    async with create_client_server_memory_streams() as (client_streams, server_streams):
        async with anyio.create_task_group() as tasks:
            tasks.start_soon(lambda: server.run(*server_streams, server.create_initialization_options()))
            async with mcp.ClientSession(*client_streams) as session:
                yield await connected(session)
            tasks.cancel_scope.cancel()
