"""``safeembodai guard-node`` as a process: it guards a served room's /cmd_vel, and SIGTERM ends it with a
stop sent to the base and exit status 0."""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest

roslibpy = pytest.importorskip("roslibpy", reason="the rosbridge extra: pip install -e '.[rosbridge]'")

pytestmark = pytest.mark.slow


def test_guard_node_forwards_then_stops_the_base_when_ended(serve_robot, tmp_path):
    session = serve_robot("scenarios/of.yaml")
    node = subprocess.Popen([sys.executable, "-m", "safeembodai_core", "guard-node", "--rosbridge",
                             f"ws://127.0.0.1:{session.port}", "--robot", "docs/examples/robot.yaml"],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ros = roslibpy.Ros(host="127.0.0.1", port=session.port)
    ros.run(timeout=10)
    try:
        deadline = time.monotonic() + 20
        while "/cmd_vel_in" not in ros.get_topics() and time.monotonic() < deadline:
            time.sleep(0.1)
        planner = roslibpy.Topic(ros, "/cmd_vel_in", "geometry_msgs/msg/Twist")
        planner.advertise()
        for _ in range(10):
            planner.publish(roslibpy.Message({"linear": {"x": 0.05, "y": 0.0, "z": 0.0},
                                              "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}))
            time.sleep(0.1)
    finally:
        ros.close()
    node.send_signal(signal.SIGTERM)
    out, err = node.communicate(timeout=20)
    assert node.returncode == 0, err
    assert "sent" in out and "decisions published" in out
    steps = session.room.record.store.steps(session.room.record.spec.trial_id)
    assert any("linear.x 0.05" in step.instruction for step in steps)  # guarded commands reached the base
    assert "linear.x 0 m/s, angular.z 0 rad/s" in steps[-1].instruction  # and the last one it sent: a stop
