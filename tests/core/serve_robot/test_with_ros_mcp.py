"""serve-robot driven by ros-mcp (PyPI ``ros-mcp``, robotmcp/ros-mcp-server), unchanged, through the official
MCP client: its read-only tools answer from the served room, and ``publish_for_durations`` on ``/cmd_vel``
moves the robot as far as the room's own record says it should.

ros-mcp runs from a virtual environment of its own (it depends on ``opencv-python``, which must not share one
with our ``opencv-python-headless``): ``SAFEEMBODAI_ROS_MCP`` names its ``ros-mcp`` script, else ``ros-mcp`` on
PATH; ``.ci/run`` makes that environment. ros-mcp starts on its built-in default of 127.0.0.1:9090, so the client
first calls its ``connect_to_robot`` tool with the served port, as an agent told the address would.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import time

import pytest

pytestmark = pytest.mark.slow

mcp = pytest.importorskip("mcp", reason="the MCP client comes with the rosbridge extra: pip install -e '.[rosbridge]'")
from mcp.client.stdio import StdioServerParameters, get_default_environment, stdio_client  # noqa: E402

TWIST = "geometry_msgs/msg/Twist"
SPEED = 0.2  # m/s: what the commands ask for
#: 30 mm is 0.15 s at SPEED. The room holds the speed from the first streamed command's arrival to the stop's;
#: ros-mcp sends the stop once its 10 Hz loop has run 1.5 s, so that span is 1.5 s plus scheduling delays (300.1 mm
#: measured on an idle machine; more slack for a busy CI one). Durations ignored would be far outside: the stop
#: lost (held to cmd_vel_timeout) is +100 mm, a publish-once hold is 100 mm in all.
TOLERANCE_MM = 30.0


@contextlib.asynccontextmanager
async def ros_mcp(script, port, folder):
    """ros-mcp (its ``script``) over stdio, connected to the served room on ``port``; yields
    ``call(tool, **arguments)``, which returns the tool's reply as a dict. ros-mcp's stderr goes to
    ``folder/ros-mcp.log``; it writes any image it receives under ``folder/camera``."""
    environment = {**get_default_environment(),
                   # no network: no update check of fastmcp's banner (and no banner on stderr)
                   "FASTMCP_CHECK_FOR_UPDATES": "off", "FASTMCP_SHOW_CLI_BANNER": "false"}
    server = StdioServerParameters(command=script, args=[], env=environment, cwd=str(folder))
    with open(folder / "ros-mcp.log", "w") as errors:
        async with stdio_client(server, errlog=errors) as (read, write):
            async with mcp.ClientSession(read, write) as client:
                await asyncio.wait_for(client.initialize(), 30)

                async def call(tool, **arguments):
                    result = await asyncio.wait_for(client.call_tool(tool, arguments), 20)
                    text = " ".join(getattr(part, "text", "") for part in result.content)
                    assert not result.isError, f"{tool} failed: {text}"
                    reply = result.structuredContent if result.structuredContent is not None else json.loads(text)
                    assert "error" not in reply, f"{tool}: {reply['error']}"
                    return reply

                connected = await call("connect_to_robot", ip="127.0.0.1", port=port)
                assert connected["connectivity_test"]["port_check"]["open"], connected
                assert "warning" not in connected, connected["warning"]  # the ROS 2 probe was answered
                yield call




def wait_for(predicate, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.02)
    return predicate()


def test_ros_mcp_read_only_tools_answer_from_the_served_room(serve_robot, ros_mcp_script, tmp_path):
    session = serve_robot("scenarios/of.yaml")

    async def ask():
        async with ros_mcp(ros_mcp_script, session.port, tmp_path) as call:
            return {"topics": await call("get_topics"), "scan_type": await call("get_topic_type", topic="/scan"),
                    "scan": await call("subscribe_once", topic="/scan", msg_type="sensor_msgs/msg/LaserScan"),
                    "nodes": await call("get_nodes"), "services": await call("get_services")}

    replies = asyncio.run(ask())
    topics = replies["topics"]
    assert set(topics["topics"]) >= {"/scan", "/odom", "/cmd_vel", "/camera/image_raw/compressed",
                                     "/safeembodai/events"}
    assert dict(zip(topics["topics"], topics["types"]))["/cmd_vel"] == TWIST
    assert replies["scan_type"] == {"topic": "/scan", "type": "sensor_msgs/msg/LaserScan"}
    scan = replies["scan"]["msg"]
    assert len(scan["ranges"]) == 360 and scan["range_max"] == pytest.approx(6.0)
    assert all(r is None or scan["range_min"] <= r <= scan["range_max"] for r in scan["ranges"])
    assert set(replies["nodes"]["nodes"]) == {"/rosapi", "/safeembodai_robot"}
    assert {"/rosapi/topics", "/rosapi/topic_type", "/rosapi/nodes", "/rosapi/services",
            "/rosapi/get_ros_version"} <= set(replies["services"]["services"])


def test_ros_mcp_publish_for_durations_drives_the_distance_asked(serve_robot, ros_mcp_script, tmp_path):
    """Streamed (``rate_hz`` 10), 0.2 m/s for 1.5 s then a stop drives 0.30 m; ros-mcp's default ``rate_hz``
    0 publishes each message once, so the room holds it for ``cmd_vel_timeout`` (0.5 s: 0.10 m), as
    ros2_control's diff_drive_controller would, whatever the duration asked. Partial messages, as ros-mcp's
    own examples send them: the server fills in the zeros."""
    session = serve_robot("scenarios/of.yaml")
    record = session.room.record
    go, stop = {"linear": {"x": SPEED}}, {"linear": {"x": 0.0}}

    async def drive():
        async with ros_mcp(ros_mcp_script, session.port, tmp_path) as call:
            scan = (await call("subscribe_once", topic="/scan", msg_type="sensor_msgs/msg/LaserScan"))["msg"]
            assert all(r is None or r > 1.0 for r in scan["ranges"][-20:] + scan["ranges"][:21]), "not open ahead"
            streamed = await call("publish_for_durations", topic="/cmd_vel", msg_type=TWIST, messages=[go, stop],
                                  durations=[1.5, 0.3], rate_hz=10)
            await asyncio.sleep(0.3)  # the stop was the last command: nothing more is driven
            streamed_mm, streamed_steps = record.distance_mm, record.steps
            await call("publish_for_durations", topic="/cmd_vel", msg_type=TWIST, messages=[go], durations=[1.5])
            return streamed, streamed_mm, streamed_steps

    streamed, streamed_mm, streamed_steps = asyncio.run(drive())
    assert streamed_steps == streamed["published_count"]  # every command reached the room
    assert streamed_mm == pytest.approx(SPEED * 1.5 * 1000, abs=TOLERANCE_MM)
    session.stop("test")
    assert wait_for(lambda: record.result is not None)
    result = record.result
    assert result.collisions == 0
    assert result.steps == streamed_steps + 1
    once_mm = result.distance_mm - streamed_mm
    # held by the room's own timer, so no client's timing enters: 100.0 mm measured
    assert once_mm == pytest.approx(SPEED * session.rates.cmd_vel_timeout_s * 1000, abs=5.0)
    start, end = result.trajectory[0], result.trajectory[-1]
    straight_mm = math.dist((start.x_mm, start.y_mm), (end.x_mm, end.y_mm))
    assert straight_mm == pytest.approx(result.distance_mm, abs=2.0)  # forward in a line, as commanded
    direction = math.atan2(end.y_mm - start.y_mm, end.x_mm - start.x_mm)
    assert math.cos(math.radians(start.heading_deg) - direction) > 0.99
