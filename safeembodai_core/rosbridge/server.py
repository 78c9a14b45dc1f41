"""A rosbridge v2 server: JSON over a WebSocket, in a thread of its own, for a process that is a robot.

The process says what it publishes (:meth:`RosbridgeServer.offer_topic`), what clients may publish
to it (:meth:`~RosbridgeServer.accept_topic`, with a handler per message) and which services it
provides (:meth:`~RosbridgeServer.add_service`); :meth:`~RosbridgeServer.start` binds and serves in a
background thread with its own asyncio loop; :meth:`~RosbridgeServer.publish` is called from any
thread and never blocks. The rosapi services are answered from what the server knows
(:mod:`.rosapi`), and clients may also publish to each other on topics they advertise.

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
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable, Sequence

from aiohttp import WSCloseCode, WSMsgType, web

from ..logs import get_logger
from .connection import Connection
from .errors import RosbridgeError
from .frames import (Advertise, CallService, Frame, FrameError, Publish, SetLevel, Subscribe, Unadvertise, Unsubscribe,
                     encode_frame, read_frame)
from .loop_thread import LoopThread
from .messages import MessageError, conform, is_known
from .names import normalize_type, resolve_name
from .rosapi import SERVICE_TYPES, SERVICES, Graph, call_rosapi

log = get_logger(__name__)
TopicHandler = Callable[[str, dict[str, Any], str], None]
ServiceHandler = Callable[[dict[str, Any]], dict[str, Any]]
START_WAIT_S = STOP_WAIT_S = 10.0


class _Refused(Exception):
    """A frame the server will not carry out; the text goes back as a status message at ``level``."""

    def __init__(self, message: str, level: str = "error"):
        super().__init__(message)
        self.level = level


@dataclass(frozen=True)
class _Offered:
    type: str
    latch: bool


@dataclass(frozen=True)
class _Accepted:
    types: tuple[str, ...]
    handler: TopicHandler


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
    """

    def __init__(self, host: str = "127.0.0.1", port: int = 9090, *, node: str = "/safeembodai_robot",
                 distro: str = "jazzy", max_frame_bytes: int = 10 * 2**20, send_queue: int = 256,
                 send_timeout: float = 5.0, max_clients: int = 32, max_subscriptions: int = 100,
                 max_advertisements: int = 100, max_queue_length: int = 100, heartbeat: float | None = 20.0,
                 clock: Callable[[], float] = time.time):
        self.host, self._port = host, port
        self.node = resolve_name(node, "node")
        self.distro = distro
        self.max_frame_bytes, self.send_queue, self.send_timeout = max_frame_bytes, send_queue, send_timeout
        self.max_clients, self.max_subscriptions = max_clients, max_subscriptions
        self.max_advertisements, self.max_queue_length = max_advertisements, max_queue_length
        self.heartbeat, self._clock = heartbeat, clock
        # registries are replaced, never changed in place: any thread reads a consistent one
        self._offered: dict[str, _Offered] = {}
        self._accepted: dict[str, _Accepted] = {}
        self._services: dict[str, tuple[str, ServiceHandler]] = {}
        self._clients: dict[str, Connection] = {}
        self._latched: dict[str, str] = {}
        self._listened: frozenset[str] = frozenset()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._worker: LoopThread | None = None
        self._runner: web.AppRunner | None = None
        self._handlers = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="rosbridge-handler")
        self._numbers = itertools.count(1)
        self._lock = threading.Lock()
        self._stopped = False

    # -- what the process serves (any thread, before or after start) ---------------------------------

    def _check_new_topic(self, topic: str) -> None:
        if topic in self._offered or topic in self._accepted:
            raise ValueError(f"topic {topic} is already offered or accepted")

    def offer_topic(self, name: str, type: str, *, latch: bool = False) -> None:
        """A topic this process publishes (``/scan``, ``sensor_msgs/msg/LaserScan``). With ``latch`` its
        last message goes to each new subscription at once (a sparse topic's ``subscribe_once``)."""
        topic = resolve_name(name)
        self._check_new_topic(topic)
        self._offered = {**self._offered, topic: _Offered(normalize_type(type), latch)}

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
        self._accepted = {**self._accepted, topic: _Accepted(kinds, handler)}

    def add_service(self, name: str, type: str, handler: ServiceHandler) -> None:
        """A service: ``handler(args)`` returns the response's values; a ``ValueError`` it raises is
        answered ``result: false`` with its text."""
        service = resolve_name(name, "service")
        if service in SERVICES or service in self._services:
            raise ValueError(f"service {service} already exists")
        self._services = {**self._services, service: (normalize_type(type, "srv"), handler)}

    def publish(self, topic: str, msg: dict[str, Any]) -> None:
        """Send ``msg`` to every subscriber of the offered ``topic``: thread-safe, never blocks. The
        message is encoded at once (later changes to ``msg`` are not sent); nothing is done while no
        client listens, or when the server is not running."""
        name = resolve_name(topic)
        offered = self._offered.get(name)
        if offered is None:
            raise ValueError(f"topic {name} is not offered (offer_topic first)")
        loop = self._loop
        if loop is None or self._stopped or not (offered.latch or name in self._listened):
            return
        frame = encode_frame({"op": "publish", "topic": name, "msg": msg})
        try:
            loop.call_soon_threadsafe(self._deliver, name, frame, offered.latch)
        except RuntimeError:  # the loop closed meanwhile: the server is stopping
            return

    @property
    def port(self) -> int:
        """The port: the bound one once started (``port=0`` picks a free one)."""
        return self._port

    def clients(self) -> int:
        """How many clients are connected now."""
        return len(self._clients)

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
        runner = web.AppRunner(app, access_log=None, handle_signals=False)
        await runner.setup()
        try:
            await web.TCPSite(runner, self.host, self._port, shutdown_timeout=1.0).start()
        except BaseException:
            await runner.cleanup()
            raise
        self._runner = runner
        self._port = int(runner.addresses[0][1])

    async def _shutdown(self) -> None:
        await asyncio.gather(*(client.shut(WSCloseCode.GOING_AWAY, "the server is stopping")
                               for client in list(self._clients.values())), return_exceptions=True)
        if self._runner is not None:
            await self._runner.cleanup()

    # -- one client -----------------------------------------------------------------------------------

    async def _serve(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(max_msg_size=self.max_frame_bytes, heartbeat=self.heartbeat, compress=False)
        if not ws.can_prepare(request).ok:
            return web.Response(status=400, text="a rosbridge v2 server: connect with a WebSocket\n")
        if self._stopped or len(self._clients) >= self.max_clients:
            log.warning("rosbridge.client_refused", clients=len(self._clients), limit=self.max_clients)
            return web.Response(status=503, text="too many rosbridge clients\n")
        await ws.prepare(request)
        peer = request.transport.get_extra_info("peername") if request.transport else None
        where = f"{peer[0]}:{peer[1]}" if isinstance(peer, tuple) else "?"
        client = Connection(f"c{next(self._numbers)}@{where}", ws, request.transport, self.send_queue)
        self._clients[client.id] = client
        log.info("rosbridge.connected", client=client.id, clients=len(self._clients))
        writer = asyncio.get_running_loop().create_task(client.write(self.send_timeout))
        try:
            await self._read(client)
        except Exception:
            log.exception("rosbridge.client_failed", client=client.id)
        finally:
            writer.cancel()
            self._clients.pop(client.id, None)
            self._refresh_listened()
            if not ws.closed:
                await client.shut(WSCloseCode.GOING_AWAY if self._stopped else WSCloseCode.OK, "closed")
            log.info("rosbridge.disconnected", client=client.id, dropped=client.outbox.dropped(),
                     clients=len(self._clients))
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
            await self._dispatch(client, frame)
        except _Refused as refused:
            log.info("rosbridge.refused", client=client.id, level=refused.level, reason=str(refused))
            client.status(refused.level, str(refused), frame.id)
        except Exception:
            log.exception("rosbridge.frame_failed", client=client.id, op=type(frame).__name__)
            client.status("error", "the server failed to carry out this frame", frame.id)

    async def _dispatch(self, client: Connection, frame: Frame) -> None:
        if isinstance(frame, Publish):
            await self._publish_from(client, frame)
        elif isinstance(frame, Subscribe):
            self._subscribe(client, frame)
        elif isinstance(frame, Unsubscribe):
            self._unsubscribe(client, frame)
        elif isinstance(frame, Advertise):
            self._advertise(client, frame)
        elif isinstance(frame, Unadvertise):
            if frame.topic not in client.advertised:
                raise _Refused(f"{frame.topic} was not advertised by this client", "warning")
            del client.advertised[frame.topic]
        elif isinstance(frame, CallService):
            await self._call(client, frame)
        elif isinstance(frame, SetLevel):
            client.level = frame.level
        else:
            raise _Refused(f"{type(frame).__name__} frames are sent by a server, not by a client")

    # -- the ops --------------------------------------------------------------------------------------

    def _types_of(self, topic: str) -> tuple[str, ...] | None:
        if topic in self._offered:
            return (self._offered[topic].type,)
        if topic in self._accepted:
            return self._accepted[topic].types
        advertised = {c.advertised[topic] for c in self._clients.values() if topic in c.advertised}
        return tuple(sorted(advertised)) or None

    def _advertise(self, client: Connection, frame: Advertise) -> None:
        topic, kind = frame.topic, frame.type
        if topic in self._offered:
            raise _Refused(f"{topic} is published by this server: clients cannot publish to it")
        accepted = self._accepted.get(topic)
        if accepted is not None and kind not in accepted.types:
            raise _Refused(f"{topic} takes {' or '.join(accepted.types)}, not {kind}")
        others = {c.advertised[topic] for c in self._clients.values() if c is not client and topic in c.advertised}
        if others - {kind}:
            raise _Refused(f"{topic} is already advertised as {others.pop()}, not {kind}")
        if topic not in client.advertised and len(client.advertised) >= self.max_advertisements:
            raise _Refused(f"one client may advertise at most {self.max_advertisements} topics")
        client.advertised[topic] = kind

    def _subscribe(self, client: Connection, frame: Subscribe) -> None:
        types = self._types_of(frame.topic)
        if types is None and frame.type is None:
            raise _Refused(f"{frame.topic} does not exist: give its type to subscribe before it is advertised")
        if types is not None and frame.type is not None and frame.type not in types:
            raise _Refused(f"{frame.topic} is {' or '.join(types)}, not {frame.type}")
        if frame.queue_length > self.max_queue_length:
            raise _Refused(f"queue_length {frame.queue_length} is more than the limit of {self.max_queue_length}")
        key = (frame.topic, frame.id)
        if key not in client.subscriptions and len(client.subscriptions) >= self.max_subscriptions:
            raise _Refused(f"one client may hold at most {self.max_subscriptions} subscriptions")
        client.subscriptions[key] = (frame.throttle_rate, frame.queue_length)
        client.refresh_outlet(frame.topic)
        self._refresh_listened()
        latched = self._latched.get(frame.topic)
        if latched is not None:
            client.outbox.offer(frame.topic, latched)

    def _unsubscribe(self, client: Connection, frame: Unsubscribe) -> None:
        keys = [key for key in client.subscriptions
                if key[0] == frame.topic and (frame.id is None or key[1] == frame.id)]
        if not keys:
            which = f" with id {frame.id}" if frame.id is not None else ""
            raise _Refused(f"no subscription to {frame.topic}{which}", "warning")
        for key in keys:
            del client.subscriptions[key]
        client.refresh_outlet(frame.topic)
        self._refresh_listened()

    def _fit(self, topic: str, kinds: Sequence[str], msg: dict[str, Any]) -> tuple[str, dict[str, Any]]:
        """The first of ``kinds`` that ``msg`` fits, and ``msg`` with its missing fields filled in."""
        stamp = _stamp(self._clock())
        errors = []
        for kind in kinds:
            try:
                return kind, conform(kind, msg, stamp)
            except MessageError as error:
                errors.append(f"{kind}: {error}")
        raise _Refused(f"{topic} takes {' or '.join(kinds)}; this message fits none ({'; '.join(errors)})")

    async def _publish_from(self, client: Connection, frame: Publish) -> None:
        topic, msg = frame.topic, frame.msg
        advertised = client.advertised.get(topic)
        accepted = self._accepted.get(topic)
        if accepted is not None:  # rosbridge publishes on a known topic without an advertise too
            kind, msg = self._fit(topic, (advertised,) if advertised else accepted.types, msg)
            await self._handler(topic, accepted.handler, kind, msg, client.id)
        elif advertised is not None:
            msg = self._fit(topic, (advertised,), msg)[1] if is_known(advertised) else msg
        elif topic in self._offered:
            raise _Refused(f"{topic} is published by this server: clients cannot publish to it")
        else:
            raise _Refused(f"{topic} was never advertised by this client: advertise it first")
        self._deliver(topic, encode_frame({"op": "publish", "topic": topic, "msg": msg}))

    async def _handler(self, topic: str, handler: Callable[..., Any], *args: Any) -> Any:
        try:
            return await asyncio.get_running_loop().run_in_executor(self._handlers, handler, *args)
        except ValueError as error:
            raise _Refused(f"{topic}: {error}") from None
        except Exception:
            log.exception("rosbridge.handler_failed", name=topic)
            raise _Refused(f"{topic}: the server failed to handle this") from None

    async def _call(self, client: Connection, frame: CallService) -> None:
        name = frame.service
        response: dict[str, Any] = {"op": "service_response", "service": name}
        if frame.id is not None:
            response["id"] = frame.id
        try:
            if name in SERVICES:
                values = call_rosapi(name, self._graph(), frame.args)
            elif name in self._services:
                values = await self._handler(name, self._services[name][1], dict(frame.args))
                if not isinstance(values, dict):
                    log.error("rosbridge.service_bad_answer", service=name, answer=type(values).__name__)
                    raise _Refused(f"{name}: the server failed to handle this")
            else:
                raise ValueError(f"service {name} does not exist")
        except (ValueError, _Refused) as error:  # one reply per call: ros-mcp reads the next frame as it
            response.update(values=str(error), result=False)
        else:
            response.update(values=values, result=True)
        client.reply(response)

    # -- the graph and delivery ----------------------------------------------------------------------

    def _graph(self) -> Graph:
        topics = {name: offered.type for name, offered in self._offered.items()}
        topics.update((name, accepted.types[0]) for name, accepted in self._accepted.items())
        advertised = {topic: kind for c in self._clients.values() for topic, kind in c.advertised.items()}
        for topic, kind in advertised.items():
            topics.setdefault(topic, kind)
        subscribed = {topic for c in self._clients.values() for topic, _ in c.subscriptions}
        services = {**SERVICE_TYPES, **{name: kind for name, (kind, _) in self._services.items()}}
        return Graph(self.node, self.distro, self._clock(), topics, frozenset(self._offered) | frozenset(advertised),
                     frozenset(self._accepted) | frozenset(subscribed), services)

    def _refresh_listened(self) -> None:
        self._listened = frozenset(topic for c in self._clients.values() for topic in c.outbox.outlets)

    def _deliver(self, topic: str, frame: str, latch: bool = False) -> None:
        if latch:
            self._latched[topic] = frame
        for client in list(self._clients.values()):
            client.outbox.offer(topic, frame)


def _stamp(now: float) -> dict[str, int]:
    sec = int(now // 1)
    return {"sec": sec, "nanosec": min(int((now - sec) * 1e9), 999_999_999)}
