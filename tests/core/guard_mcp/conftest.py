"""guard-mcp without processes: scans as rosbridge sends them, a clock the test moves, an upstream that records.

``rig(**policy)`` builds :class:`~safeembodai_core.guard_mcp.proxy.GuardMcp` around a fake upstream (it answers
ros-mcp's shapes and advances the clock by what it is asked to publish) and senses fed by hand; ``rig.sent`` is
what the upstream was asked, ``rig.stops`` what guard-mcp's own connection published.
"""

from __future__ import annotations

import asyncio
import json
import math
from types import SimpleNamespace

import pytest

from safeembodai_core import Guard
from safeembodai_core.guard_mcp.judging import MotionJudge
from safeembodai_core.guard_mcp.policy import read_policy
from safeembodai_core.guard_mcp.senses import RobotSenses
from safeembodai_core.ros.robot_file import RobotFile

ROBOT = ("127.0.0.1", 9090)


def scan_message(ranges):
    """360 beams counter-clockwise from the heading, metres, ``null`` where REP 117 says ``inf``."""
    message = {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "base_scan"}, "angle_min": 0.0,
               "angle_max": 2 * math.pi * 359 / 360, "angle_increment": 2 * math.pi / 360, "time_increment": 0.0,
               "scan_time": 0.1, "range_min": 0.02, "range_max": 6.0, "ranges": ranges, "intensities": []}
    return json.loads(json.dumps(message))


def wall_at(metres):
    """A wall across the heading ``metres`` ahead (every beam within 80 degrees of ahead reaches it)."""
    ranges = [None] * 360
    for k in list(range(81)) + list(range(280, 360)):
        ranges[k] = min(metres / math.cos(math.radians(k)), 5.9)
    return ranges


def twist(x=0.0, z=0.0):
    return {"linear": {"x": x, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": z}}


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


class Rig:
    """A GuardMcp on a fake upstream and hand-fed senses (module docstring)."""

    def __init__(self, policy, robot):
        from safeembodai_core.guard_mcp.proxy import GuardMcp

        self.clock = Clock()
        self.sent: list[tuple[str, dict]] = []
        self.stops: list[tuple[str, dict]] = []
        self.during_slice = None  # called with the slice's arguments, as if the world moved meanwhile
        self.fail_slices = False
        self.latest = None
        self.senses = RobotSenses(robot, scan_timeout_s=policy.scan_timeout_s, odom_topic=None, clock=self.clock)
        self.senses.client = SimpleNamespace(advertise=lambda topic, type_: None, unadvertise=lambda topic: None,
                                             publish=lambda topic, msg: self.stops.append((topic, msg)))
        guard = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": policy.margin_mm}}],
                      robot=robot.robot_spec())
        self.mcp = GuardMcp(policy, MotionJudge(guard, robot, policy), self.senses, self.upstream, ROBOT)

    async def upstream(self, tool, arguments):
        from mcp import types

        self.sent.append((tool, arguments))
        if tool == "publish_for_durations":
            if self.during_slice is not None:
                self.during_slice(arguments)
            seconds = sum(arguments["durations"])
            self.clock.now += seconds
            if self.latest is not None:
                self.see(self.latest)  # the scan keeps arriving
            if self.fail_slices:
                content = {"error": "rosbridge refused it"}
            else:
                content = {"success": True, "published_count": max(1, round(seconds * 10))}
        else:
            content = {"upstream": tool, "arguments": arguments}
        return types.CallToolResult(content=[types.TextContent(type="text", text=json.dumps(content))],
                                    structuredContent=content)

    def see(self, ranges):
        self.latest = ranges
        self.senses.on_scan(scan_message(ranges))

    def call(self, tool, **arguments):
        result = asyncio.run(self.mcp.call(tool, arguments))
        return result.isError, result.structuredContent

    @property
    def slices(self):
        return [arguments for tool, arguments in self.sent if tool == "publish_for_durations"]


@pytest.fixture
def rig():
    """``rig(mode="limit", ...)``: a :class:`Rig` under the shipped policy with those keys changed (it needs the MCP
    SDK: the test skips without it)."""
    pytest.importorskip("mcp", reason="guard-mcp needs the MCP SDK: pip install -e '.[mcp]'")

    def make(robot=None, **changes):
        policy = read_policy().model_copy(update=changes)
        robot = robot or RobotFile(radius_mm=170.0, scans={"/scan": {"null_range": "no_return"}})
        return Rig(policy, robot)

    return make


@pytest.fixture
def scans():
    return SimpleNamespace(message=scan_message, wall_at=wall_at, open=lambda: [None] * 360, twist=twist)
