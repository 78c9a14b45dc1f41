"""``safeembodai guard-node``: :class:`~.node.GuardNode` on a rosbridge connection.

A rosbridge client (:class:`~safeembodai_core.rosbridge.client.RosbridgeClient`) subscribes to the
scan, the odometry and the planner's command topic, advertises the base's command topic and
``/safeembodai/guard``, and runs the node's cycle on a timer (``period_s``). Each cycle's twist goes to
the base; its decision goes to ``/safeembodai/guard`` when its kind (the action, and what its reasons are
about) differs from the last one published, and otherwise at most every :data:`RECORD_PERIOD_S` while
its numbers change (a held command judged the same way is not repeated there, only to the base). Messages are handled in
the client's thread, the timer in its own; the node's lock keeps them apart.

If the connection to rosbridge is lost, nothing more can be sent: the base's own command timeout
(``diff_drive_controller``'s ``cmd_vel_timeout``) is what stops it then. The node says so and ends.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import structlog

from ..serve_robot import messages
from .node import STOP, GuardNode, Sent, twist_message

log = structlog.get_logger(__name__)

DECISIONS_TOPIC = "/safeembodai/guard"
#: The least time between two decision records of the same kind (seconds).
RECORD_PERIOD_S = 0.5
ODOMETRY = "nav_msgs/msg/Odometry"


class GuardWire:
    """The node on the wire (module docstring)."""

    def __init__(self, node: GuardNode, url: str, *, command_in: str = "/cmd_vel_in", command_out: str = "/cmd_vel",
                 scan: str | None = None, odom: str | None = "/odom", period_s: float = 0.05) -> None:
        self.node, self.url = node, url
        self.command_in, self.command_out = command_in, command_out
        self.scan, self.odom = scan or node.scan_topic, odom
        self.period_s = period_s
        self.client: Any = None
        self.decisions = 0
        self.sent = 0
        self._last_record: tuple[Any, ...] | None = None
        self._last_sent: Sent | None = None
        self._recorded_at = -RECORD_PERIOD_S
        self._stop = threading.Event()
        self._lock = threading.Lock()

    def start(self) -> None:
        """Connect, subscribe and advertise; raises the client's error when rosbridge cannot be reached."""
        from ..rosbridge.client import RosbridgeClient

        client = RosbridgeClient(self.url, on_close=self._lost).connect()
        self.client = client
        client.advertise(self.command_out, messages.TWIST)
        client.advertise(DECISIONS_TOPIC, messages.STRING)
        client.subscribe(self.scan, messages.LASER_SCAN, lambda m: self.node.on_scan(m, time.monotonic()),
                         queue_length=1)
        if self.odom:
            client.subscribe(self.odom, ODOMETRY, lambda m: self.node.on_odom(m, time.monotonic()), queue_length=1)
        client.subscribe(self.command_in, messages.TWIST, self._command, queue_length=1)

    def _command(self, message: Any) -> None:
        self._send(self.node.on_command(message, time.monotonic()))

    def _send(self, sent: Sent | None) -> None:
        if sent is None or self.client is None:
            return
        now = time.monotonic()
        with self._lock:
            self.client.publish(self.command_out, twist_message(sent.twist))
            self.sent += 1
            # a new kind of decision goes out at once; the same kind with other numbers (a limit's factor)
            # at most every RECORD_PERIOD_S
            key = (sent.action, tuple(reason.split(":")[0] for reason in sent.reasons))
            if key != self._last_record or (now - self._recorded_at >= RECORD_PERIOD_S and sent != self._last_sent):
                self._last_record, self._recorded_at, self._last_sent = key, now, sent
                self.decisions += 1
                self.client.publish(DECISIONS_TOPIC, sent.record(now))

    def _lost(self, why: str) -> None:
        log.error("guard_node.connection_lost", url=self.url, why=why,
                  advice="the base's own cmd_vel timeout stops it now")
        self._stop.set()

    def run(self) -> None:
        """Run the timer's cycles until :meth:`stop` or the connection is lost."""
        next_at = time.monotonic()
        while not self._stop.is_set():
            self._send(self.node.cycle(time.monotonic()))
            next_at += self.period_s
            self._stop.wait(max(0.0, next_at - time.monotonic()))

    def stop(self, reason: str = "stopped") -> None:
        """End the node: a last stop to the base, then close (any thread, a signal handler too)."""
        log.info("guard_node.stopping", reason=reason)
        self._stop.set()

    def close(self) -> None:
        """Send the base a stop and close the connection."""
        if self.client is not None:
            try:
                with self._lock:
                    self.client.publish(self.command_out, twist_message(STOP))
            finally:
                self.client.close()
                self.client = None

