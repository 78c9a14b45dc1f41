"""The server's graph and what each client op does to it.

:class:`Bridge` holds what the process offers, accepts and serves, the clients connected, and the
last message of each latched topic; :meth:`Bridge.dispatch` carries out one client frame on the
server's event loop: advertise, publish (checked against its type, then the process's handler on the
handler thread, then relayed), subscribe and unsubscribe, a service call (rosapi's, or one the process
added), the status level. A frame it will not carry out raises :class:`Refused`, whose text the
client gets as a status message. Only the event loop's thread touches a ``Bridge``, except
:attr:`Bridge.offered`, :attr:`Bridge.accepted`, :attr:`Bridge.services` and :attr:`Bridge.listened`,
which are replaced, never changed in place, so any thread reads a consistent one.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
from dataclasses import dataclass, field
from typing import Any, Callable, Sequence

from ..logs import get_logger
from .connection import Connection
from .frames import (Advertise, CallService, Frame, Publish, SetLevel, Subscribe, Unadvertise, Unsubscribe,
                     encode_frame)
from .messages import MessageError, conform, is_known, time_of
from .rosapi import SERVICE_TYPES, SERVICES, Graph, call_rosapi

log = get_logger(__name__)
TopicHandler = Callable[[str, dict[str, Any], str], None]
ServiceHandler = Callable[[dict[str, Any]], dict[str, Any]]


class Refused(Exception):
    """A frame the server will not carry out; the text goes back as a status message at ``level``."""

    def __init__(self, message: str, level: str = "error"):
        super().__init__(message)
        self.level = level


@dataclass(frozen=True)
class Offered:
    """A topic the process publishes."""

    type: str
    latch: bool


@dataclass(frozen=True)
class Accepted:
    """A topic clients publish to, its types and the process's handler."""

    types: tuple[str, ...]
    handler: TopicHandler


@dataclass(frozen=True)
class Limits:
    """What one client may hold."""

    max_subscriptions: int
    max_advertisements: int
    max_queue_length: int


@dataclass
class Bridge:
    """The graph and the ops (module docstring)."""

    node: str
    distro: str
    clock: Callable[[], float]
    limits: Limits
    handlers: concurrent.futures.Executor
    offered: dict[str, Offered] = field(default_factory=dict)
    accepted: dict[str, Accepted] = field(default_factory=dict)
    services: dict[str, tuple[str, ServiceHandler]] = field(default_factory=dict)
    clients: dict[str, Connection] = field(default_factory=dict)
    latched: dict[str, str] = field(default_factory=dict)
    listened: frozenset[str] = frozenset()

    async def dispatch(self, client: Connection, frame: Frame) -> None:
        """Carry out ``frame`` for ``client``; :class:`Refused` says why not."""
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
                raise Refused(f"{frame.topic} was not advertised by this client", "warning")
            del client.advertised[frame.topic]
        elif isinstance(frame, CallService):
            await self._call(client, frame)
        elif isinstance(frame, SetLevel):
            client.level = frame.level
        else:
            raise Refused(f"{type(frame).__name__} frames are sent by a server, not by a client")

    def _types_of(self, topic: str) -> tuple[str, ...] | None:
        if topic in self.offered:
            return (self.offered[topic].type,)
        if topic in self.accepted:
            return self.accepted[topic].types
        advertised = {c.advertised[topic] for c in self.clients.values() if topic in c.advertised}
        return tuple(sorted(advertised)) or None

    def _advertise(self, client: Connection, frame: Advertise) -> None:
        topic, kind = frame.topic, frame.type
        if topic in self.offered:
            raise Refused(f"{topic} is published by this server: clients cannot publish to it")
        accepted = self.accepted.get(topic)
        if accepted is not None and kind not in accepted.types:
            raise Refused(f"{topic} takes {' or '.join(accepted.types)}, not {kind}")
        others = {c.advertised[topic] for c in self.clients.values() if c is not client and topic in c.advertised}
        if others - {kind}:
            raise Refused(f"{topic} is already advertised as {others.pop()}, not {kind}")
        if topic not in client.advertised and len(client.advertised) >= self.limits.max_advertisements:
            raise Refused(f"one client may advertise at most {self.limits.max_advertisements} topics")
        client.advertised[topic] = kind

    def _subscribe(self, client: Connection, frame: Subscribe) -> None:
        types = self._types_of(frame.topic)
        if types is None and frame.type is None:
            raise Refused(f"{frame.topic} does not exist: give its type to subscribe before it is advertised")
        if types is not None and frame.type is not None and frame.type not in types:
            raise Refused(f"{frame.topic} is {' or '.join(types)}, not {frame.type}")
        if frame.queue_length > self.limits.max_queue_length:
            raise Refused(f"queue_length {frame.queue_length} is more than the limit of {self.limits.max_queue_length}")
        key = (frame.topic, frame.id)
        if key not in client.subscriptions and len(client.subscriptions) >= self.limits.max_subscriptions:
            raise Refused(f"one client may hold at most {self.limits.max_subscriptions} subscriptions")
        client.subscriptions[key] = (frame.throttle_rate, frame.queue_length)
        client.refresh_outlet(frame.topic)
        self.refresh_listened()
        latched = self.latched.get(frame.topic)
        if latched is not None:
            client.outbox.offer(frame.topic, latched)

    def _unsubscribe(self, client: Connection, frame: Unsubscribe) -> None:
        keys = [key for key in client.subscriptions
                if key[0] == frame.topic and (frame.id is None or key[1] == frame.id)]
        if not keys:
            which = f" with id {frame.id}" if frame.id is not None else ""
            raise Refused(f"no subscription to {frame.topic}{which}", "warning")
        for key in keys:
            del client.subscriptions[key]
        client.refresh_outlet(frame.topic)
        self.refresh_listened()

    def _fit(self, topic: str, kinds: Sequence[str], msg: dict[str, Any]) -> tuple[str, dict[str, Any]]:
        """The first of ``kinds`` that ``msg`` fits, and ``msg`` with its missing fields filled in."""
        stamp = time_of(self.clock())
        errors = []
        for kind in kinds:
            try:
                return kind, conform(kind, msg, stamp)
            except MessageError as error:
                errors.append(f"{kind}: {error}")
        raise Refused(f"{topic} takes {' or '.join(kinds)}; this message fits none ({'; '.join(errors)})")

    async def _publish_from(self, client: Connection, frame: Publish) -> None:
        topic, msg = frame.topic, frame.msg
        advertised = client.advertised.get(topic)
        accepted = self.accepted.get(topic)
        if accepted is not None:  # rosbridge publishes on a known topic without an advertise too
            kind, msg = self._fit(topic, (advertised,) if advertised else accepted.types, msg)
            await self._handler(topic, accepted.handler, kind, msg, client.id)
        elif advertised is not None:
            msg = self._fit(topic, (advertised,), msg)[1] if is_known(advertised) else msg
        elif topic in self.offered:
            raise Refused(f"{topic} is published by this server: clients cannot publish to it")
        else:
            raise Refused(f"{topic} was never advertised by this client: advertise it first")
        self.deliver(topic, encode_frame({"op": "publish", "topic": topic, "msg": msg}))

    async def _handler(self, topic: str, handler: Callable[..., Any], *args: Any) -> Any:
        try:
            return await asyncio.get_running_loop().run_in_executor(self.handlers, handler, *args)
        except ValueError as error:
            raise Refused(f"{topic}: {error}") from None
        except Exception:
            log.exception("rosbridge.handler_failed", name=topic)
            raise Refused(f"{topic}: the server failed to handle this") from None

    async def _call(self, client: Connection, frame: CallService) -> None:
        name = frame.service
        response: dict[str, Any] = {"op": "service_response", "service": name}
        if frame.id is not None:
            response["id"] = frame.id
        try:
            if name in SERVICES:
                values = call_rosapi(name, self.graph(), frame.args)
            elif name in self.services:
                values = await self._handler(name, self.services[name][1], dict(frame.args))
                if not isinstance(values, dict):
                    log.error("rosbridge.service_bad_answer", service=name, answer=type(values).__name__)
                    raise Refused(f"{name}: the server failed to handle this")
            else:
                raise ValueError(f"service {name} does not exist")
        except (ValueError, Refused) as error:  # one reply per call: ros-mcp reads the next frame as it
            response.update(values=str(error), result=False)
        else:
            response.update(values=values, result=True)
        client.reply(response)

    def graph(self) -> Graph:
        """What the rosapi services answer from, now."""
        topics = {name: offered.type for name, offered in self.offered.items()}
        topics.update((name, accepted.types[0]) for name, accepted in self.accepted.items())
        advertised = {topic: kind for c in self.clients.values() for topic, kind in c.advertised.items()}
        for topic, kind in advertised.items():
            topics.setdefault(topic, kind)
        subscribed = {topic for c in self.clients.values() for topic, _ in c.subscriptions}
        services = {**SERVICE_TYPES, **{name: kind for name, (kind, _) in self.services.items()}}
        return Graph(self.node, self.distro, self.clock(), topics, frozenset(self.offered) | frozenset(advertised),
                     frozenset(self.accepted) | frozenset(subscribed), services)

    def refresh_listened(self) -> None:
        """Recount the topics some client subscribes to (read by ``publish`` in other threads)."""
        self.listened = frozenset(topic for c in self.clients.values() for topic in c.outbox.outlets)

    def deliver(self, topic: str, frame: str, latch: bool = False) -> None:
        """Offer a ``publish`` frame of ``topic`` to every client (kept by those subscribed)."""
        if latch:
            self.latched[topic] = frame
        for client in list(self.clients.values()):
            client.outbox.offer(topic, frame)
