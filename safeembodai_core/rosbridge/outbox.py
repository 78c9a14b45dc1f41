"""What the server has to send one client, bounded however slowly the client reads.

A client's frames wait in its :class:`Outbox` until its writer can send them, and nothing in it
grows with the client's slowness:

* **replies** (status messages, service responses) wait in order, at most ``max_replies``; one
  more means the client asks without reading the answers, and :meth:`Outbox.reply` says so (the
  server then closes the connection);
* **messages of a subscribed topic** wait in that topic's :class:`Outlet`, at most ``queue_length``
  of them (at least one): a new message beyond that pushes out the oldest, as rosbridge's queue
  does. With ``throttle_rate`` the outlet lets one message go per ``throttle_rate`` ms; with a
  throttle and no queue, a message arriving before the throttle has passed is dropped (rosbridge's
  ``ThrottleMessageHandler``), so a throttled client never gets stale messages.

Several subscriptions of one client to one topic share its outlet, with the smallest throttle and
the largest queue among them (rosbridge's rule), so each message goes to the client once.
Replies go before topic messages; among topics the message that has waited longest goes first.
"""

from __future__ import annotations

import asyncio
import itertools
import math
from collections import deque
from typing import Callable


class Outlet:
    """One topic's messages waiting for one client."""

    def __init__(self, throttle_rate_ms: int = 0, queue_length: int = 0):
        self.throttle_s = throttle_rate_ms / 1000.0
        self.queue_length = queue_length
        self.pending: deque[tuple[int, str]] = deque(maxlen=max(queue_length, 1))
        self.last_sent = -math.inf
        self.dropped = 0

    def configure(self, throttle_rate_ms: int, queue_length: int) -> None:
        """New settings; the newest waiting messages that still fit are kept."""
        self.throttle_s = throttle_rate_ms / 1000.0
        self.queue_length = queue_length
        self.pending = deque(self.pending, maxlen=max(queue_length, 1))

    def offer(self, seq: int, frame: str, now: float) -> None:
        """A new message; the oldest waiting one goes when the queue is full."""
        if self.queue_length == 0 and now < self.last_sent + self.throttle_s:
            self.dropped += 1
            return
        if len(self.pending) == self.pending.maxlen:
            self.dropped += 1
        self.pending.append((seq, frame))

    def ready_at(self) -> float | None:
        """When the next waiting message may go (None: none waits)."""
        return self.last_sent + self.throttle_s if self.pending else None

    def take(self, now: float) -> str:
        """The next message, sent now."""
        self.last_sent = now
        return self.pending.popleft()[1]


class Outbox:
    """Everything waiting for one client: replies first, then topic messages by age.

    :param clock: monotonic seconds (``time.monotonic``; a test may pass its own).
    """

    def __init__(self, max_replies: int, clock: Callable[[], float]):
        self.max_replies = max_replies
        self.replies: deque[str] = deque()
        self.outlets: dict[str, Outlet] = {}
        self._clock = clock
        self._seq = itertools.count()
        self._wake = asyncio.Event()

    def reply(self, frame: str) -> bool:
        """Queue a reply; False when ``max_replies`` already wait (the client does not read)."""
        if len(self.replies) >= self.max_replies:
            return False
        self.replies.append(frame)
        self._wake.set()
        return True

    def offer(self, topic: str, frame: str) -> None:
        """A message of ``topic``, kept if the client subscribes to it."""
        outlet = self.outlets.get(topic)
        if outlet is not None:
            outlet.offer(next(self._seq), frame, self._clock())
            self._wake.set()

    def dropped(self) -> int:
        """Topic messages dropped so far for this client (queue full, or inside the throttle)."""
        return sum(outlet.dropped for outlet in self.outlets.values())

    def _next(self) -> tuple[str | None, float | None]:
        """The frame to send now, or how long until one may go (None: until something arrives)."""
        if self.replies:
            return self.replies.popleft(), None
        now = self._clock()
        best: Outlet | None = None
        wait: float | None = None
        for outlet in self.outlets.values():
            at = outlet.ready_at()
            if at is None:
                continue
            if at <= now:
                if best is None or outlet.pending[0][0] < best.pending[0][0]:
                    best = outlet
            else:
                wait = at - now if wait is None else min(wait, at - now)
        return (best.take(now), None) if best is not None else (None, wait)

    async def next_frame(self) -> str:
        """Wait for the next frame that may go to the client."""
        while True:
            frame, wait = self._next()
            if frame is not None:
                return frame
            self._wake.clear()
            try:
                await asyncio.wait_for(self._wake.wait(), wait)
            except asyncio.TimeoutError:
                continue

