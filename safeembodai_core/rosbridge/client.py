"""A small rosbridge v2 client for a program made of threads (``guard-node``).

:class:`RosbridgeClient` connects to ``ws://HOST:PORT`` (any rosbridge server: a real robot's, or
this package's), then advertises, publishes, subscribes and calls services from any thread. Its
WebSocket lives in a thread of its own with an asyncio loop; :meth:`~RosbridgeClient.publish` queues
a frame and returns; :meth:`~RosbridgeClient.call_service` waits for its answer.

What the server sends is outside bytes: every frame goes through :func:`~.frames.read_frame`, and a
frame it refuses (or a binary one, or one of an op a client does not take) is logged and dropped; the
connection goes on. A subscription's callback gets the message as the server sent it (the frame is
checked, the content is the caller's to read with a strict reader of its type, such as
:meth:`~safeembodai_core.ros.LaserScan.from_ros`). Callbacks run on the client's thread, one at a time
in arrival order: keep them short; they may publish, but not call a service (that would wait on the
thread that must deliver the answer). An exception in a callback is logged, never raised.

There is no reconnection: when the connection ends other than by :meth:`~RosbridgeClient.close`,
``on_close(reason)`` is called once, :attr:`~RosbridgeClient.closed_reason` says why, waiting service
calls fail and every later call raises :class:`~.errors.RosbridgeError`.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import threading
from collections import deque
from typing import Any, Callable

import aiohttp

from ..logs import get_logger
from .errors import RosbridgeError, ServiceCallError
from .frames import FrameError, Publish, ServiceResponse, Status, encode_frame, read_frame
from .loop_thread import LoopThread
from .names import normalize_type, resolve_name

log = get_logger(__name__)
Callback = Callable[[dict[str, Any]], None]


class RosbridgeClient:
    """A rosbridge v2 client (module docstring). Use it as a context manager, or :meth:`connect` and
    :meth:`close`.

    :param url: ``ws://HOST:PORT`` of the rosbridge server.
    :param timeout: seconds to connect, and a service call's default wait.
    :param max_frame_bytes: a bigger frame from the server ends the connection.
    :param send_queue: frames that may wait to be sent; one more raises :class:`RosbridgeError`.
    :param on_close: called once, with the reason, when the connection ends other than by :meth:`close`.
    :param on_status: called with each ``status`` message the server sends (they are logged anyway).
    """

    def __init__(self, url: str, *, timeout: float = 5.0, max_frame_bytes: int = 10 * 2**20, send_queue: int = 1000,
                 on_close: Callable[[str], None] | None = None, on_status: Callable[[Status], None] | None = None):
        self.url, self.timeout, self.max_frame_bytes, self.send_queue = url, timeout, max_frame_bytes, send_queue
        self._on_close, self._on_status = on_close, on_status
        self._worker: LoopThread | None = None
        self._session: aiohttp.ClientSession | None = None
        self._ws: aiohttp.ClientWebSocketResponse[bool] | None = None
        self._outgoing: deque[str] = deque()
        self._wake: asyncio.Event | None = None
        self._subscriptions: dict[str, tuple[str, Callback]] = {}  # replaced, never changed in place
        self._pending: dict[str, concurrent.futures.Future[ServiceResponse]] = {}
        self._lock = threading.Lock()
        self._numbers = itertools.count(1)
        self._closing = False
        self.closed_reason: str | None = None

    def __enter__(self) -> RosbridgeClient:
        return self.connect()

    def __exit__(self, *exc_info: Any) -> None:
        self.close()

    @property
    def connected(self) -> bool:
        """Whether the connection is open (connected, not lost, not closed)."""
        return self._ws is not None and self.closed_reason is None and not self._closing

    # -- connecting and closing -----------------------------------------------------------------------

    def connect(self) -> RosbridgeClient:
        """Open the connection; :class:`RosbridgeError` when the server cannot be reached in ``timeout``."""
        if self._worker is not None:
            raise RosbridgeError("this client was already connected")
        worker = self._worker = LoopThread("rosbridge-client")
        try:
            worker.run(self._open(), self.timeout + 1.0)
        except Exception as error:
            worker.stop(self.timeout)
            self._worker = None  # connect() may be tried again
            reason = "timed out" if isinstance(error, TimeoutError) else str(error) or type(error).__name__
            raise RosbridgeError(f"cannot reach rosbridge at {self.url}: {reason}") from None
        log.info("rosbridge_client.connected", url=self.url)
        return self

    async def _open(self) -> None:
        self._wake = asyncio.Event()
        session = self._session = aiohttp.ClientSession()

        async def handshake() -> aiohttp.ClientWebSocketResponse[bool]:
            return await session.ws_connect(self.url, max_msg_size=self.max_frame_bytes, heartbeat=20.0, compress=0)

        try:
            ws = self._ws = await asyncio.wait_for(handshake(), self.timeout)
        except BaseException:
            await session.close()
            raise
        loop = asyncio.get_running_loop()
        loop.create_task(self._read(ws))
        loop.create_task(self._write(ws, self._wake))

    def close(self) -> None:
        """Close the connection and end the client's thread; idempotent."""
        worker = self._worker
        if worker is None or self._closing:
            return
        if worker.inside():
            raise RosbridgeError("close() cannot be called from a subscription callback")
        self._closing = True
        try:
            worker.run(self._shut(), self.timeout)
        except Exception as error:
            log.warning("rosbridge_client.close_incomplete", error=repr(error))
        self._fail_pending("the client was closed")
        worker.stop(self.timeout)
        log.info("rosbridge_client.closed", url=self.url)

    async def _shut(self) -> None:
        if self._ws is not None:
            await self._ws.close()
        if self._session is not None:
            await self._session.close()

    # -- sending --------------------------------------------------------------------------------------

    def _send(self, frame: dict[str, Any]) -> None:
        if self.closed_reason is not None:
            raise RosbridgeError(f"the connection to {self.url} is lost: {self.closed_reason}")
        if not self.connected or self._worker is None or self._wake is None:
            raise RosbridgeError(f"not connected to {self.url}")
        if len(self._outgoing) >= self.send_queue:
            raise RosbridgeError(f"{self.send_queue} frames wait to be sent: the server does not read")
        self._outgoing.append(encode_frame(frame))
        self._worker.call_soon(self._wake.set)

    async def _write(self, ws: aiohttp.ClientWebSocketResponse[bool], wake: asyncio.Event) -> None:
        try:
            while not ws.closed:
                await wake.wait()
                wake.clear()
                while self._outgoing:
                    await ws.send_str(self._outgoing.popleft())
        except (ConnectionError, RuntimeError) as error:
            log.info("rosbridge_client.send_failed", error=str(error))

    def advertise(self, topic: str, type: str) -> None:
        """Say that this client publishes ``topic`` of ``type`` (``geometry_msgs/msg/Twist``)."""
        normalize_type(type)
        self._send({"op": "advertise", "topic": resolve_name(topic), "type": type})

    def unadvertise(self, topic: str) -> None:
        """Stop publishing ``topic``."""
        self._send({"op": "unadvertise", "topic": resolve_name(topic)})

    def publish(self, topic: str, msg: dict[str, Any]) -> None:
        """Queue ``msg`` on ``topic`` and return (the server answers only a refusal, as a status)."""
        self._send({"op": "publish", "topic": resolve_name(topic), "msg": msg})

    def subscribe(self, topic: str, type: str, callback: Callback, throttle_rate: int = 0,
                  queue_length: int = 1) -> str:
        """Call ``callback(msg)`` with each message of ``topic``; returns the subscription's id."""
        normalize_type(type)
        name = resolve_name(topic)
        subscription = f"subscribe:{name}:{next(self._numbers)}"
        with self._lock:
            self._subscriptions = {**self._subscriptions, subscription: (name, callback)}
        self._send({"op": "subscribe", "id": subscription, "topic": name, "type": type,
                    "throttle_rate": throttle_rate, "queue_length": queue_length})
        return subscription

    def unsubscribe(self, subscription: str) -> None:
        """End the subscription ``subscription`` (the id :meth:`subscribe` returned)."""
        with self._lock:
            topic, _ = self._subscriptions[subscription]
            self._subscriptions = {key: value for key, value in self._subscriptions.items() if key != subscription}
        self._send({"op": "unsubscribe", "id": subscription, "topic": topic})

    def call_service(self, name: str, args: dict[str, Any] | None = None,
                     timeout: float | None = None) -> dict[str, Any]:
        """The values the service ``name`` answers to ``args``.

        :raises ServiceCallError: the service answered ``result: false`` (the message is its reason), or
            gave no answer within ``timeout`` seconds (default: the client's).
        """
        if self._worker is not None and self._worker.inside():
            raise RosbridgeError("call_service cannot wait inside a subscription callback")
        service = resolve_name(name, "service")
        wait = self.timeout if timeout is None else timeout
        call = f"call_service:{service}:{next(self._numbers)}"
        answer: concurrent.futures.Future[ServiceResponse] = concurrent.futures.Future()
        with self._lock:
            self._pending[call] = answer
        try:
            self._send({"op": "call_service", "id": call, "service": service, "args": args or {}})
            response = answer.result(wait)
        except concurrent.futures.TimeoutError:
            raise ServiceCallError(f"{service}: no answer within {wait:g} s") from None
        finally:
            with self._lock:
                self._pending.pop(call, None)
        if not response.result:
            raise ServiceCallError(f"{service}: {response.values}")
        if not isinstance(response.values, dict):
            raise ServiceCallError(f"{service}: the answer's values are not an object")
        return response.values

    # -- receiving ------------------------------------------------------------------------------------

    async def _read(self, ws: aiohttp.ClientWebSocketResponse[bool]) -> None:
        reason = "the server closed the connection"
        try:
            async for message in ws:
                if message.type is aiohttp.WSMsgType.TEXT:
                    self._receive(message.data)
                elif message.type is aiohttp.WSMsgType.BINARY:
                    log.warning("rosbridge_client.binary_frame_dropped", size=len(message.data))
                elif message.type is aiohttp.WSMsgType.ERROR:
                    reason = f"connection error: {message.data}"
                    break
            if ws.close_code is not None:
                reason = f"{reason} (code {ws.close_code})"
        except Exception as error:
            reason = f"connection error: {error!r}"
        if not self._closing:
            self._lost(reason)

    def _receive(self, text: str) -> None:
        try:
            frame = read_frame(text, self.max_frame_bytes)
        except FrameError as error:
            log.warning("rosbridge_client.frame_dropped", reason=str(error))
            return
        if isinstance(frame, Publish):
            for topic, callback in self._subscriptions.values():
                if topic == frame.topic:
                    self._call_back(callback, frame.msg, topic)
        elif isinstance(frame, ServiceResponse):
            with self._lock:
                answer = self._pending.get(frame.id) if isinstance(frame.id, str) else None
            if answer is None:
                log.warning("rosbridge_client.unexpected_response", service=frame.service, id=frame.id)
            elif not answer.done():
                answer.set_result(frame)
        elif isinstance(frame, Status):
            log.warning("rosbridge_client.status", level=frame.level, msg=frame.msg, id=frame.id)
            if self._on_status is not None:
                self._call_back(self._on_status, frame, "status")
        else:
            log.warning("rosbridge_client.frame_dropped", reason=f"a client does not take {type(frame).__name__}")

    def _call_back(self, callback: Callable[[Any], None], value: Any, what: str) -> None:
        try:
            callback(value)
        except Exception:
            log.exception("rosbridge_client.callback_failed", what=what)

    def _lost(self, reason: str) -> None:
        self.closed_reason = reason
        log.warning("rosbridge_client.connection_lost", url=self.url, reason=reason)
        self._fail_pending(f"the connection is lost: {reason}")
        if self._on_close is not None:
            self._call_back(self._on_close, reason, "on_close")

    def _fail_pending(self, reason: str) -> None:
        with self._lock:
            pending, self._pending = self._pending, {}
        for answer in pending.values():
            if not answer.done():
                answer.set_exception(RosbridgeError(reason))
