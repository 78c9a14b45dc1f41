"""guard-node between a roslibpy publisher and serve-robot: a command into a wall ends as a stop before
contact, on the room's own record (not the guard's log)."""

from __future__ import annotations

import json
import threading
import time

import pytest

from safeembodai_core import Guard
from safeembodai_core.guard_node.node import GuardNode
from safeembodai_core.guard_node.wire import GuardWire
from safeembodai_core.ros.robot_file import RobotFile

roslibpy = pytest.importorskip("roslibpy", reason="the rosbridge extra: pip install -e '.[rosbridge]'")

pytestmark = pytest.mark.slow


def test_a_command_into_a_wall_ends_as_a_stop_before_contact(serve_robot):
    session = serve_robot("scenarios/of.yaml", speed=2.0)
    robot = RobotFile(radius_mm=170.0, scans={"/scan": {"null_range": "no_return"}})
    guard = Guard(["command_limits", {"use": "swept_body", "options": {"margin_mm": 50.0}}], robot=robot.robot_spec())
    wire = GuardWire(GuardNode(guard, robot), f"ws://127.0.0.1:{session.port}")
    wire.start()
    cycles = threading.Thread(target=wire.run, daemon=True)
    cycles.start()
    ros = roslibpy.Ros(host="127.0.0.1", port=session.port)
    ros.run(timeout=10)
    decisions = []
    try:
        roslibpy.Topic(ros, "/safeembodai/guard", "std_msgs/msg/String").subscribe(
            lambda m: decisions.append(json.loads(m["data"])))
        planner = roslibpy.Topic(ros, "/cmd_vel_in", "geometry_msgs/msg/Twist")
        planner.advertise()
        time.sleep(0.3)
        deadline = time.monotonic() + 40
        while time.monotonic() < deadline and not (decisions and decisions[-1]["action"] == "stop"
                                                    and decisions[-1]["reasons"]
                                                    and "no command" not in decisions[-1]["reasons"][0]):
            planner.publish(roslibpy.Message({"linear": {"x": 0.2, "y": 0.0, "z": 0.0},
                                              "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}))
            time.sleep(0.1)
        time.sleep(1.0)
    finally:
        ros.close()
        wire.stop()
        cycles.join(5)
        wire.close()
    session.stop("test")
    deadline = time.monotonic() + 20
    while session.room.record.result is None and time.monotonic() < deadline:
        time.sleep(0.05)
    result = session.room.record.result
    assert decisions and decisions[-1]["action"] == "stop", decisions[-3:]
    assert result.collisions == 0 and result.outcome.value == "timeout", result  # the room's record: no contact
    assert result.distance_mm > 300  # it did drive, towards the wall, before the guard stopped it
    assert any(d["action"] == "limit" for d in decisions)
