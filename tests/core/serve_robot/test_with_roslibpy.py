"""serve-robot driven by roslibpy, a rosbridge client no one here wrote: it senses, moves as commanded, and
the session's record holds the path it drove."""

from __future__ import annotations

import math
import time

import pytest

roslibpy = pytest.importorskip("roslibpy", reason="the rosbridge extra: pip install -e '.[rosbridge]'")


def wait_for(predicate, timeout=10.0):
    deadline = time.monotonic() + timeout
    while not predicate() and time.monotonic() < deadline:
        time.sleep(0.02)
    return predicate()


def position(odometry):
    p = odometry["pose"]["pose"]["position"]
    return p["x"], p["y"]


def test_roslibpy_senses_drives_and_the_record_holds_the_path(serve_robot):
    session = serve_robot("scenarios/of.yaml")
    ros = roslibpy.Ros(host="127.0.0.1", port=session.port)
    ros.run(timeout=10)
    try:
        assert set(ros.get_topics()) >= {"/scan", "/odom", "/cmd_vel", "/camera/image_raw/compressed",
                                         "/safeembodai/events"}
        assert ros.get_topic_type("/scan") == "sensor_msgs/msg/LaserScan"
        scans, odometry = [], []
        roslibpy.Topic(ros, "/scan", "sensor_msgs/msg/LaserScan").subscribe(scans.append)
        roslibpy.Topic(ros, "/odom", "nav_msgs/msg/Odometry").subscribe(odometry.append)
        assert wait_for(lambda: scans and odometry)
        scan = scans[-1]
        assert len(scan["ranges"]) == 360 and scan["range_max"] == pytest.approx(6.0)
        open_beam = max(range(360), key=lambda k: scan["ranges"][k] if scan["ranges"][k] is not None else 99.0)
        command = roslibpy.Topic(ros, "/cmd_vel", "geometry_msgs/msg/Twist")
        command.advertise()
        turn = math.radians(open_beam if open_beam <= 180 else open_beam - 360)  # face the open side first
        for _ in range(10):
            command.publish(roslibpy.Message({"linear": {"x": 0.0, "y": 0.0, "z": 0.0},
                                              "angular": {"x": 0.0, "y": 0.0, "z": turn}}))
            time.sleep(0.1)
        command.publish(roslibpy.Message({"linear": {"x": 0.0, "y": 0.0, "z": 0.0},
                                          "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}))
        time.sleep(0.3)
        start = position(odometry[-1])
        for _ in range(10):  # 0.1 m/s for 1 s, then the last one held 0.5 s more (cmd_vel_timeout)
            command.publish(roslibpy.Message({"linear": {"x": 0.1, "y": 0.0, "z": 0.0},
                                              "angular": {"x": 0.0, "y": 0.0, "z": 0.0}}))
            time.sleep(0.1)
        time.sleep(1.0)
        end = position(odometry[-1])
        travelled = math.dist(start, end)
        assert 0.12 <= travelled <= 0.17, travelled
    finally:
        ros.close()
    session.stop("test")
    assert wait_for(lambda: session.room is not None and session.room.record.result is not None)
    result = session.room.record.result
    assert result.steps == 21 and result.collisions == 0  # every command received is a step
    recorded = result.trajectory[-1]
    assert math.dist((recorded.x_mm / 1000, recorded.y_mm / 1000), end) < 0.005  # the record's path is the odometry's
    assert result.distance_mm == pytest.approx(travelled * 1000, abs=10.0)
