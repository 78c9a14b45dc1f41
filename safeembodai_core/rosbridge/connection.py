"""One client connected to the server: its WebSocket, outbox, subscriptions and advertisements."""

from __future__ import annotations

import asyncio
import contextlib
import time
from typing import Any

from aiohttp import WSCloseCode, web

from ..logs import get_logger
from .frames import LEVELS, FrameId, encode_frame
from .outbox import Outbox, Outlet

log = get_logger(__name__)
CLOSE_WAIT_S = 1.0


class Connection:
    """A client's state on the server's event loop (only that loop's thread touches it).

    :param client_id: how the server's handlers and logs name this client (``c3@127.0.0.1:50412``).
    """

    def __init__(self, client_id: str, ws: web.WebSocketResponse, transport: Any, send_queue: int):
        self.id = client_id
        self.ws = ws
        self.transport = transport
        self.outbox = Outbox(send_queue, time.monotonic)
        #: (topic, subscription id) -> (throttle_rate ms, queue_length)
        self.subscriptions: dict[tuple[str, FrameId], tuple[int, int]] = {}
        #: topic -> type, the topics this client advertised
        self.advertised: dict[str, str] = {}
        self.level = "error"
        self.closing = False
        self._closer: asyncio.Task[None] | None = None

    def refresh_outlet(self, topic: str) -> None:
        """Give ``topic``'s outlet the merged settings of this client's subscriptions to it (or drop it)."""
        settings = [value for (name, _), value in self.subscriptions.items() if name == topic]
        if not settings:
            self.outbox.outlets.pop(topic, None)
            return
        throttle = min(throttle for throttle, _ in settings)
        queue = max(queue for _, queue in settings)
        outlet = self.outbox.outlets.get(topic)
        if outlet is None:
            self.outbox.outlets[topic] = Outlet(throttle, queue)
        else:
            outlet.configure(throttle, queue)

    def reply(self, frame: dict[str, Any]) -> None:
        """Queue a reply; a client that lets ``send_queue`` replies pile up is closed."""
        if self.closing:
            return
        if not self.outbox.reply(encode_frame(frame)):
            log.warning("rosbridge.client_not_reading", client=self.id, waiting=len(self.outbox.replies))
            self.close(WSCloseCode.POLICY_VIOLATION, "too many replies waiting: the client does not read")

    def status(self, level: str, message: str, frame_id: FrameId = None) -> None:
        """A status message, if the client's level asks for it (``set_level``; ``error`` by default)."""
        if self.level == "none" or LEVELS.index(level) < LEVELS.index(self.level):
            return
        frame: dict[str, Any] = {"op": "status", "level": level, "msg": message}
        if frame_id is not None:
            frame["id"] = frame_id
        self.reply(frame)

    def close(self, code: int, reason: str) -> None:
        """Close the connection from the server's side, without waiting (the reader then ends)."""
        if self.closing:
            return
        self.closing = True
        log.info("rosbridge.closing", client=self.id, code=int(code), reason=reason)
        self._closer = asyncio.get_running_loop().create_task(self.shut(code, reason))

    async def shut(self, code: int, reason: str) -> None:
        """Send the close frame; drop the TCP connection if the client does not take it in time (a
        graceful close would wait for ever to flush what the client never reads)."""
        self.closing = True
        clean = False
        try:
            await asyncio.wait_for(self.ws.close(code=code, message=reason.encode()[:120]), CLOSE_WAIT_S)
            clean = True
        except (asyncio.TimeoutError, ConnectionError, RuntimeError):
            pass
        finally:  # a cancelled close too (aiohttp cancels a drain the connection will never finish)
            if not clean and self.transport is not None:
                with contextlib.suppress(Exception):
                    self.transport.abort()

    async def write(self, send_timeout: float) -> None:
        """Send what the outbox holds until the connection ends; a send the client does not take within
        ``send_timeout`` seconds closes it (it stopped reading)."""
        while not self.closing:
            frame = await self.outbox.next_frame()
            try:
                await asyncio.wait_for(self.ws.send_str(frame), send_timeout)
            except asyncio.TimeoutError:
                log.warning("rosbridge.send_timeout", client=self.id, seconds=send_timeout,
                            dropped=self.outbox.dropped())
                self.close(WSCloseCode.POLICY_VIOLATION, "the client stopped reading")
                return
            except (ConnectionError, RuntimeError):
                return
