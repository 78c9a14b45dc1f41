"""Hostile or broken commands to serve-robot, sent as raw frames by a WebSocket client that is not ours: the
sender gets a status error, the robot stops, another client keeps being served, and the record stays whole."""

from __future__ import annotations

import asyncio
import json
import time

import aiohttp
import pytest

TWIST = "geometry_msgs/msg/Twist"


def twist_frame(x, z=0.0, topic="/cmd_vel"):
    return json.dumps({"op": "publish", "topic": topic,
                       "msg": {"linear": {"x": x, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": z}}})


async def exchange(url: str, frames: list[str], listen_s: float) -> list[dict]:
    """Advertise /cmd_vel, send ``frames`` in order, and collect what comes back for ``listen_s``."""
    async with aiohttp.ClientSession() as session, session.ws_connect(url) as ws:
        await ws.send_str(json.dumps({"op": "advertise", "topic": "/cmd_vel", "type": TWIST}))
        for frame in frames:
            await ws.send_str(frame)
        replies, deadline = [], time.monotonic() + listen_s
        while time.monotonic() < deadline:
            try:
                message = await ws.receive(timeout=max(deadline - time.monotonic(), 0.01))
            except asyncio.TimeoutError:
                break
            if message.type is aiohttp.WSMsgType.TEXT:
                replies.append(json.loads(message.data))
            elif message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING):
                break
        return replies


async def watch_odometry(url: str, seconds: float) -> list[dict]:
    async with aiohttp.ClientSession() as session, session.ws_connect(url) as ws:
        await ws.send_str(json.dumps({"op": "subscribe", "topic": "/odom", "type": "nav_msgs/msg/Odometry"}))
        got, deadline = [], time.monotonic() + seconds
        while time.monotonic() < deadline:
            try:
                message = await ws.receive(timeout=max(deadline - time.monotonic(), 0.01))
            except asyncio.TimeoutError:
                break
            if message.type is aiohttp.WSMsgType.TEXT:
                got.append(json.loads(message.data))
        return got


BAD = {
    "nan": twist_frame("NaN").replace('"NaN"', "NaN"),
    "infinity": twist_frame("Infinity").replace('"Infinity"', "Infinity"),
    "huge integer": twist_frame(10 ** 400),
    "overflowing float": twist_frame("X").replace('"X"', "1e400"),
    "text speed": twist_frame("fast"),
    "bool speed": twist_frame(True),
    "wrong type": json.dumps({"op": "publish", "topic": "/cmd_vel", "msg": {"data": "forward"}}),
    "not json": "{op: publish",
    "unadvertised topic": twist_frame(0.2, topic="/elsewhere"),
}


@pytest.mark.parametrize("kind", list(BAD))
def test_a_bad_command_gets_a_status_error_and_the_robot_stops(serve_robot, kind):
    session = serve_robot("scenarios/of.yaml")
    url = f"ws://127.0.0.1:{session.port}"

    async def scenario():
        watcher = asyncio.create_task(watch_odometry(url, 1.6))
        replies = await exchange(url, [twist_frame(0.1), BAD[kind]], 1.2)
        return replies, await watcher

    replies, odometry = asyncio.run(scenario())
    errors = [r for r in replies if r.get("op") == "status" and r.get("level") == "error"]
    assert errors, (kind, replies)
    assert "Traceback" not in json.dumps(errors)
    speeds = [o["msg"]["twist"]["twist"]["linear"]["x"] for o in odometry if o.get("op") == "publish"]
    assert speeds, "the other client was served"
    assert speeds[-1] == 0.0  # stopped: by the bad command, or by the timeout of the good one before it
    session.stop("test")
    deadline = time.monotonic() + 10
    while session.room.record.result is None and time.monotonic() < deadline:
        time.sleep(0.02)
    result = session.room.record.result
    assert result is not None and result.steps >= 1 and result.collisions == 0
    assert result.distance_mm <= 0.1 * 1000 * (0.5 + 0.1)  # at most the good command's hold


def test_an_absurd_but_finite_command_is_driven_at_the_bases_limits_and_said_so(serve_robot, run_store, plugins):
    session = serve_robot("scenarios/of.yaml")
    url = f"ws://127.0.0.1:{session.port}"
    replies = asyncio.run(exchange(url, [twist_frame(1.7e308, -1e308)], 0.8))
    assert not [r for r in replies if r.get("level") == "error"], replies
    session.stop("test")
    deadline = time.monotonic() + 10
    while session.room.record.result is None and time.monotonic() < deadline:
        time.sleep(0.02)
    record = session.room.record
    with run_store(record.scenario, plugins, record.path) as store:  # the session closes its own once it ends
        [step] = store.steps(record.spec.trial_id)
    assert step.accepted and "linear.x 1.7e+308 m/s, angular.z -1e+308 rad/s" in step.instruction
    [executed] = step.executed
    assert "base's limits" in executed.result.detail or executed.result.collided
    assert abs(executed.result.distance_mm) <= 200.0 * 0.5 + 1e-6  # 200 mm/s for the 0.5 s hold, no more
