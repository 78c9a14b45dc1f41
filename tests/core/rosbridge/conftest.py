"""A served robot on a free port, and clients that are not ours: raw aiohttp WebSockets and raw TCP
sockets (to send what no WebSocket library would: a frame cut off, a client that never reads)."""

from __future__ import annotations

import asyncio
import base64
import json
import os
import socket
import struct
import threading
import time
from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import aiohttp
import pytest

from safeembodai_core.rosbridge.server import RosbridgeServer

WAIT_S = 2.0


@dataclass
class Robot:
    """The served robot: its server, and what its handlers were given."""

    server: RosbridgeServer
    commands: list[tuple[str, dict[str, Any], str]] = field(default_factory=list)

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.server.port}"

    def wait_for_commands(self, count: int, timeout: float = WAIT_S) -> list[tuple[str, dict[str, Any], str]]:
        deadline = time.monotonic() + timeout
        while len(self.commands) < count and time.monotonic() < deadline:
            time.sleep(0.01)
        return self.commands


def serve(**options: Any) -> Robot:
    """A started server with the topics and services the tests use (``stop()`` it)."""
    robot = Robot(RosbridgeServer(port=0, **{"send_timeout": 0.5, **options}))
    server = robot.server
    server.offer_topic("/scan", "sensor_msgs/msg/LaserScan")
    server.offer_topic("/camera/image_raw/compressed", "sensor_msgs/msg/CompressedImage")
    server.offer_topic("/events", "std_msgs/msg/String", latch=True)

    def command(kind: str, msg: dict[str, Any], client: str) -> None:
        twist = msg["twist"] if kind.endswith("TwistStamped") else msg
        if twist["linear"]["x"] > 5:
            raise ValueError("linear.x above 5 m/s is refused")
        if twist["linear"]["x"] < -100:
            raise RuntimeError("a bug in the handler")
        robot.commands.append((kind, msg, client))

    def add(args: dict[str, Any]) -> dict[str, Any]:
        if not isinstance(args.get("a"), int) or not isinstance(args.get("b"), int):
            raise ValueError("a and b must be integers")
        return {"sum": args["a"] + args["b"]}

    server.accept_topic("/cmd_vel", ["geometry_msgs/msg/Twist", "geometry_msgs/TwistStamped"], command)
    server.add_service("/add_two_ints", "example_interfaces/srv/AddTwoInts", add)
    server.start()
    return robot


@pytest.fixture
def robot():
    served = serve()
    yield served
    served.server.stop()


@pytest.fixture
def serve_robot():
    """``serve_robot(**options)``: a server with other limits, stopped after the test."""
    started: list[Robot] = []

    def make(**options: Any) -> Robot:
        started.append(serve(**options))
        return started[-1]

    yield make
    for served in started:
        served.server.stop()


class AioThread:
    """An event loop in a thread for the raw clients (independent of the package's own)."""

    def __init__(self) -> None:
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self.loop.run_forever, daemon=True)
        self.thread.start()

    def run(self, coroutine: Any, timeout: float = WAIT_S + 1) -> Any:
        return asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(timeout)


@pytest.fixture(scope="session")
def aio():
    thread = AioThread()
    yield thread
    thread.loop.call_soon_threadsafe(thread.loop.stop)


class RawClient:
    """A plain aiohttp WebSocket: sends whatever text it is given, reads frames as JSON."""

    def __init__(self, aio: AioThread, url: str):
        self.aio = aio
        self.session, self.ws = aio.run(self._open(url))

    @staticmethod
    async def _open(url: str) -> tuple[aiohttp.ClientSession, aiohttp.ClientWebSocketResponse]:
        session = aiohttp.ClientSession()
        return session, await session.ws_connect(url, max_msg_size=0)

    def send(self, frame: Any) -> None:
        self.aio.run(self.ws.send_str(frame if isinstance(frame, str) else json.dumps(frame)))

    def send_bytes(self, data: bytes) -> None:
        self.aio.run(self.ws.send_bytes(data))

    def recv(self, timeout: float = WAIT_S) -> dict[str, Any]:
        message = self.aio.run(self.ws.receive(timeout), timeout + 1)
        assert message.type is aiohttp.WSMsgType.TEXT, f"expected a text frame, got {message.type}: {message.data}"
        return json.loads(message.data)

    def frames_within(self, seconds: float) -> list[dict[str, Any]]:
        """Every frame that arrives in the next ``seconds``."""
        frames, deadline = [], time.monotonic() + seconds
        while (left := deadline - time.monotonic()) > 0:
            try:
                frames.append(self.recv(left))
            except (asyncio.TimeoutError, TimeoutError):
                break
        return frames

    def call(self, service: str, args: Any = None, call_id: Any = "call-1") -> dict[str, Any]:
        frame = {"op": "call_service", "service": service, "id": call_id}
        if args is not None:
            frame["args"] = args
        self.send(frame)
        return self.recv()

    def closed_with(self, timeout: float = WAIT_S) -> int | None:
        """Wait until the server closes the connection; its close code."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = self.aio.run(self.ws.receive(deadline - time.monotonic()), timeout + 1)
            if message.type is aiohttp.WSMsgType.CLOSE:
                return int(message.data)  # the code the server sent (close_code may say 1006 once it hangs up)
            if message.type in (aiohttp.WSMsgType.CLOSED, aiohttp.WSMsgType.CLOSING):
                return self.ws.close_code
        raise AssertionError("the server did not close the connection")

    def close(self) -> None:
        self.aio.run(self._close())

    async def _close(self) -> None:
        await self.ws.close()
        await self.session.close()


@pytest.fixture
def connect(aio):
    """``connect(url)``: a :class:`RawClient`, closed after the test."""
    opened: list[RawClient] = []

    def make(url: str) -> RawClient:
        opened.append(RawClient(aio, url))
        return opened[-1]

    yield make
    for client in opened:
        try:
            client.close()
        except Exception:
            pass


def ws_frame(payload: bytes, opcode: int = 1, declared: int | None = None) -> bytes:
    """A masked client frame; ``declared`` may claim more payload than follows."""
    length = len(payload) if declared is None else declared
    if length < 126:
        header = struct.pack("!BB", 0x80 | opcode, 0x80 | length)
    elif length < 2**16:
        header = struct.pack("!BBH", 0x80 | opcode, 0x80 | 126, length)
    else:
        header = struct.pack("!BBQ", 0x80 | opcode, 0x80 | 127, length)
    mask = os.urandom(4)
    return header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload))


def raw_socket(port: int, receive_buffer: int | None = None) -> socket.socket:
    """A TCP connection that has done the WebSocket handshake and nothing else."""
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    if receive_buffer is not None:
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, receive_buffer)
    sock.settimeout(WAIT_S)
    sock.connect(("127.0.0.1", port))
    key = base64.b64encode(os.urandom(16)).decode()
    sock.sendall(f"GET / HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                 f"Sec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n".encode())
    answer = b""
    while b"\r\n\r\n" not in answer:
        answer += sock.recv(1)
    assert answer.startswith(b"HTTP/1.1 101"), answer
    return sock


def wait_until(condition: Any, timeout: float = WAIT_S) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return condition()


@pytest.fixture
def wire():
    """Raw TCP: ``wire.socket(port)`` (closed after the test), ``wire.frame(...)``, ``wire.wait_until(...)``."""
    opened: list[socket.socket] = []

    def open_socket(port: int, receive_buffer: int | None = None) -> socket.socket:
        opened.append(raw_socket(port, receive_buffer))
        return opened[-1]

    yield SimpleNamespace(socket=open_socket, frame=ws_frame, wait_until=wait_until)
    for sock in opened:
        sock.close()
