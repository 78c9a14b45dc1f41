"""A rosbridge v2 server: JSON over a WebSocket, in a thread of its own, for a process that is a robot.

The process says what it publishes (:meth:`RosbridgeServer.offer_topic`), what clients may publish
to it (:meth:`~RosbridgeServer.accept_topic`, with a handler per message) and which services it
provides (:meth:`~RosbridgeServer.add_service`); :meth:`~RosbridgeServer.start` binds and serves in a
background thread with its own asyncio loop; :meth:`~RosbridgeServer.publish` is called from any
thread and never blocks. The rosapi services are answered from what the server knows
(:mod:`.rosapi`), and clients may also publish to each other on topics they advertise; what each
op does is :mod:`.bridge`'s, this module is the network and the threads.

Every frame from a client goes through :func:`~.frames.read_frame`; whatever is refused gets a
``status`` message at level ``error`` (with the frame's ``id``) and the connection goes on. Handlers
run one at a time on one worker thread, never on the event loop, so a slow handler delays the
messages that reach handlers, not the traffic of every client. What each client is sent waits in a
bounded :class:`~.outbox.Outbox`; a client that stops reading is closed after ``send_timeout``. No
exception leaves the server: it is logged (structlog) and the server carries on. The protocol,
limits and refusals are listed in ``docs/rosbridge.md``.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import logging
import threading
import time
from typing import Any, Callable, Sequence

from aiohttp import WSCloseCode, WSMsgType, web

from ..logs import get_logger
from .bridge import Accepted, Bridge, Limits, Offered, Refused, ServiceHandler, TopicHandler
from .connection import Connection
from .errors import RosbridgeError
from .frames import FrameError, encode_frame, read_frame
from .loop_thread import LoopThread
from .messages import is_known
from .names import normalize_type, resolve_name
from .rosapi import SERVICES

log = get_logger(__name__)
START_WAIT_S = STOP_WAIT_S = 10.0


class _HttpComplaints(logging.Handler):
    """aiohttp's log of bad HTTP requests (TLS on the port, a missing Host): one structlog line each,
    never its traceback."""

    def emit(self, record: logging.LogRecord) -> None:
        error = record.exc_info[1] if record.exc_info else None
        log.info("rosbridge.bad_http_request", message=record.getMessage(), error=repr(error) if error else None)


def _http_logger() -> logging.Logger:
    logger = logging.getLogger(f"{__name__}.http")
    if not logger.handlers:
        logger.addHandler(_HttpComplaints())
        logger.propagate = False
    return logger


class RosbridgeServer:
    """A rosbridge v2 WebSocket server (module docstring).

    :param port: 0 picks a free port (:attr:`port` says which).
    :param node: the server's node name in the rosapi answers.
    :param distro: the ROS 2 distribution ``/rosapi/get_ros_version`` names.
    :param max_frame_bytes: a bigger frame from a client closes its connection (WebSocket code 1009).
    :param send_queue: replies that may wait for one client; one more closes it (it does not read).
    :param send_timeout: seconds a client may take to accept one frame before it is closed.
    :param max_clients: connections at once; the next is answered HTTP 503.
    :param max_subscriptions: subscriptions (topic and id) one client may hold.
    :param max_advertisements: topics one client may advertise.
    :param max_queue_length: the largest ``queue_length`` a subscription may ask for.
    :param heartbeat: seconds between WebSocket pings; a client that does not answer is closed.
    :param clock: the time of ``/rosapi/get_time`` and of missing header stamps (seconds).
    :param allowed_origins: browser origins (``https://dashboard.example:8080``) besides the server's own
        address that may connect (:meth:`origin_allowed`); any other page is answered HTTP 403.
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 9090, *, node: str = "/safeembodai_robot",
                 distro: str = "jazzy", max_frame_bytes: int = 10 * 2**20, send_queue: int = 256,
                 send_timeout: float = 5.0, max_clients: int = 32, max_subscriptions: int = 100,
                 max_advertisements: int = 100, max_queue_length: int = 100, heartbeat: float | None = 20.0,
                 clock: Callable[[], float] = time.time, allowed_origins: Sequence[str] = ()):
        self.host, self._port = host, port
        self.allowed_origins = frozenset(origin.rstrip("/").lower() for origin in allowed_origins)
        self.node = resolve_name(node, "node")
        self.max_frame_bytes, self.send_queue, self.send_timeout = max_frame_bytes, send_queue, send_timeout
        self.max_clients, self.heartbeat = max_clients, heartbeat
        self._handlers = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="rosbridge-handler")
        self._bridge = Bridge(self.node, distro, clock, Limits(max_subscriptions, max_advertisements,
                                                                max_queue_length), self._handlers)
        self._loop: asyncio.AbstractEventLoop | None = None
        self._worker: LoopThread | None = None
        self._runner: web.AppRunner | None = None
        self._numbers = itertools.count(1)
        self._lock = threading.Lock()
        self._stopped = False

    # -- what the process serves (any thread, before or after start) ---------------------------------

    def _check_new_topic(self, topic: str) -> None:
        if topic in self._bridge.offered or topic in self._bridge.accepted:
            raise ValueError(f"topic {topic} is already offered or accepted")

    def offer_topic(self, name: str, type: str, *, latch: bool = False) -> None:
        """A topic this process publishes (``/scan``, ``sensor_msgs/msg/LaserScan``). With ``latch`` its
        last message goes to each new subscription at once (a sparse topic's ``subscribe_once``)."""
        topic = resolve_name(name)
        self._check_new_topic(topic)
        bridge = self._bridge
        bridge.offered = {**bridge.offered, topic: Offered(normalize_type(type), latch)}

    def accept_topic(self, name: str, types: Sequence[str], handler: TopicHandler) -> None:
        """A topic clients may publish to, of one of ``types`` (each a type of :mod:`.messages`).

        ``handler(type, msg, client_id)`` gets each message, checked against its type with the missing
        fields filled in, on the server's handler thread; a ``ValueError`` it raises goes back to the
        client as a status error with its text.
        """
        topic = resolve_name(name)
        self._check_new_topic(topic)
        kinds = tuple(normalize_type(kind) for kind in types)
        unknown = [kind for kind in kinds if not is_known(kind)]
        if not kinds or unknown:
            raise ValueError(f"topic {topic} must accept known message types (rosbridge.messages); "
                             f"not {', '.join(unknown) or 'none'}")
        bridge = self._bridge
        bridge.accepted = {**bridge.accepted, topic: Accepted(kinds, handler)}

    def add_service(self, name: str, type: str, handler: ServiceHandler) -> None:
        """A service: ``handler(args)`` returns the response's values; a ``ValueError`` it raises is
        answered ``result: false`` with its text."""
        service = resolve_name(name, "service")
        bridge = self._bridge
        if service in SERVICES or service in bridge.services:
            raise ValueError(f"service {service} already exists")
        bridge.services = {**bridge.services, service: (normalize_type(type, "srv"), handler)}

    def publish(self, topic: str, msg: dict[str, Any]) -> None:
        """Send ``msg`` to every subscriber of the offered ``topic``: thread-safe, never blocks. The
        message is encoded at once (later changes to ``msg`` are not sent); nothing is done while no
        client listens, or when the server is not running."""
        name = resolve_name(topic)
        offered = self._bridge.offered.get(name)
        if offered is None:
            raise ValueError(f"topic {name} is not offered (offer_topic first)")
        loop = self._loop
        if loop is None or self._stopped or not (offered.latch or name in self._bridge.listened):
            return
        frame = encode_frame({"op": "publish", "topic": name, "msg": msg})
        try:
            loop.call_soon_threadsafe(self._bridge.deliver, name, frame, offered.latch)
        except RuntimeError:  # the loop closed meanwhile: the server is stopping
            return

    @property
    def port(self) -> int:
        """The port: the bound one once started (``port=0`` picks a free one)."""
        return self._port

    def clients(self) -> int:
        """How many clients are connected now."""
        return len(self._bridge.clients)

    # -- lifecycle ------------------------------------------------------------------------------------

    def start(self) -> None:
        """Bind and serve in a background thread; :class:`RosbridgeError` when the address cannot be bound."""
        with self._lock:
            if self._worker is not None or self._stopped:
                raise RosbridgeError("this rosbridge server was already started")
            worker = self._worker = LoopThread("rosbridge-server")
        try:
            worker.run(self._bind(), START_WAIT_S)
        except Exception as error:
            worker.stop(STOP_WAIT_S)
            self._worker = None
            reason = (f"it did not start within {START_WAIT_S:g} s" if isinstance(error, TimeoutError)
                      else getattr(error, "strerror", None) or str(error))
            raise RosbridgeError(f"cannot serve rosbridge on {self.host}:{self._port}: {reason}") from None
        self._loop = worker.loop
        log.info("rosbridge.listening", host=self.host, port=self._port, node=self.node)

    def stop(self) -> None:
        """Close every connection and the listener, and end the thread; idempotent."""
        with self._lock:
            worker = self._worker
            if worker is None or self._stopped:
                return
            self._stopped = True
        if worker.inside():
            raise RuntimeError("stop() must not be called from the server's own thread")
        try:
            worker.run(self._shutdown(), STOP_WAIT_S)
        except Exception as error:
            log.warning("rosbridge.stop_incomplete", error=repr(error))
        worker.stop(STOP_WAIT_S)
        self._handlers.shutdown(wait=False)
        log.info("rosbridge.stopped", port=self._port)

    async def _bind(self) -> None:
        app = web.Application()
        app.router.add_route("GET", "/{tail:.*}", self._serve)
        runner = web.AppRunner(app, access_log=None, handle_signals=False, shutdown_timeout=1.0,
                               logger=_http_logger())
        await runner.setup()
        try:
            await web.TCPSite(runner, self.host, self._port).start()
        except BaseException:
            await runner.cleanup()
            raise
        self._runner = runner
        self._port = int(runner.addresses[0][1])

    async def _shutdown(self) -> None:
        await asyncio.gather(*(client.shut(WSCloseCode.GOING_AWAY, "the server is stopping")
                               for client in list(self._bridge.clients.values())), return_exceptions=True)
        if self._runner is not None:
            await self._runner.cleanup()

    def origin_allowed(self, origin: str) -> bool:
        """Whether a browser page of ``origin`` may connect: a WebSocket is not bound by the same-origin
        rule, so any page a local browser opens could otherwise drive the robot. Allowed: this server's
        own address (``http://127.0.0.1:PORT``, ``localhost``, ``[::1]``, or the host it binds; what a
        tool such as websocket-client sends), and the origins given (``allowed_origins``: a dashboard).
        A client that sends no ``Origin`` (roslibpy, aiohttp, ros-mcp's) is no page and is not asked."""
        origin = origin.strip().rstrip("/").lower()
        if origin in self.allowed_origins:
            return True
        own = {self.host.lower(), "127.0.0.1", "localhost", "[::1]"}
        return any(origin == f"{scheme}://{host}:{self._port}" for scheme in ("http", "https", "ws", "wss")
                   for host in own)

    # -- one client -----------------------------------------------------------------------------------

    async def _serve(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(max_msg_size=self.max_frame_bytes, heartbeat=self.heartbeat, compress=False)
        if not ws.can_prepare(request).ok:
            return web.Response(status=400, text="a rosbridge v2 server: connect with a WebSocket\n")
        origin = request.headers.get("Origin")
        if origin is not None and not self.origin_allowed(origin):
            log.warning("rosbridge.origin_refused", origin=origin[:200])
            return web.Response(status=403, text="this rosbridge server does not serve pages of that origin\n")
        clients = self._bridge.clients
        if self._stopped or len(clients) >= self.max_clients:
            log.warning("rosbridge.client_refused", clients=len(clients), limit=self.max_clients)
            return web.Response(status=503, text="too many rosbridge clients\n")
        await ws.prepare(request)
        peer = request.transport.get_extra_info("peername") if request.transport else None
        where = f"{peer[0]}:{peer[1]}" if isinstance(peer, tuple) else "?"
        client = Connection(f"c{next(self._numbers)}@{where}", ws, request.transport, self.send_queue)
        clients[client.id] = client
        log.info("rosbridge.connected", client=client.id, clients=len(clients))
        writer = asyncio.get_running_loop().create_task(client.write(self.send_timeout))
        try:
            await self._read(client)
        except Exception:
            log.exception("rosbridge.client_failed", client=client.id)
        finally:
            writer.cancel()
            clients.pop(client.id, None)
            self._bridge.refresh_listened()
            if not ws.closed:
                await client.shut(WSCloseCode.GOING_AWAY if self._stopped else WSCloseCode.OK, "closed")
            log.info("rosbridge.disconnected", client=client.id, dropped=client.outbox.dropped(),
                     clients=len(clients))
        return ws

    async def _read(self, client: Connection) -> None:
        while not client.closing:
            message = await client.ws.receive()
            if message.type is WSMsgType.TEXT:
                await self._handle(client, message.data)
            elif message.type is WSMsgType.BINARY:
                client.status("error", "binary frames (CBOR, BSON) are not supported: send JSON text")
            else:  # closed, or a frame aiohttp refused (too big: code 1009; not UTF-8: 1007)
                if message.type is WSMsgType.ERROR:
                    log.warning("rosbridge.connection_error", client=client.id, error=str(message.data))
                return

    async def _handle(self, client: Connection, text: str) -> None:
        try:
            frame = read_frame(text, self.max_frame_bytes)
        except FrameError as error:
            log.info("rosbridge.frame_refused", client=client.id, reason=str(error))
            client.status("error", str(error), error.frame_id)
            return
        try:
            await self._bridge.dispatch(client, frame)
        except Refused as refused:
            log.info("rosbridge.refused", client=client.id, level=refused.level, reason=str(refused))
            client.status(refused.level, str(refused), frame.id)
        except Exception:
            log.exception("rosbridge.frame_failed", client=client.id, op=type(frame).__name__)
            client.status("error", "the server failed to carry out this frame", frame.id)
