"""What waits for one client stays bounded: rosbridge's throttle and queue, on a clock the test moves."""

from __future__ import annotations

import asyncio

import pytest

from safeembodai_core.rosbridge.outbox import Outbox, Outlet


class Clock:
    def __init__(self) -> None:
        self.now = 100.0

    def __call__(self) -> float:
        return self.now


@pytest.fixture
def loop():
    """One event loop per test: an outbox waits on the loop it first waited on."""
    running = asyncio.new_event_loop()
    yield running
    running.close()


def drain(outbox: Outbox, loop: asyncio.AbstractEventLoop) -> list[str]:
    """Every frame that may go now."""
    async def take() -> list[str]:
        frames = []
        while True:
            try:
                frames.append(await asyncio.wait_for(outbox.next_frame(), 0.01))
            except asyncio.TimeoutError:
                return frames

    return loop.run_until_complete(take())


def subscribed(throttle_ms: int = 0, queue_length: int = 0) -> tuple[Outbox, Clock]:
    clock = Clock()
    outbox = Outbox(4, clock)
    outbox.outlets["/scan"] = Outlet(throttle_ms, queue_length)
    return outbox, clock


def test_without_a_queue_a_slow_client_gets_the_newest_message_only(loop):
    outbox, _ = subscribed()
    for n in range(5):
        outbox.offer("/scan", f"m{n}")
    assert drain(outbox, loop) == ["m4"]
    assert outbox.dropped() == 4


def test_a_queue_keeps_the_newest_queue_length_messages(loop):
    outbox, _ = subscribed(queue_length=3)
    for n in range(10):
        outbox.offer("/scan", f"m{n}")
    assert drain(outbox, loop) == ["m7", "m8", "m9"]


def test_a_throttle_lets_one_message_go_per_throttle_rate(loop):
    outbox, clock = subscribed(throttle_ms=100, queue_length=5)
    for n in range(3):
        outbox.offer("/scan", f"m{n}")
    assert drain(outbox, loop) == ["m0"]
    clock.now += 0.05
    assert drain(outbox, loop) == []
    clock.now += 0.05
    assert drain(outbox, loop) == ["m1"]
    clock.now += 0.1
    assert drain(outbox, loop) == ["m2"]


def test_a_throttle_without_a_queue_drops_what_arrives_too_soon(loop):
    """rosbridge's ThrottleMessageHandler: no stale message is held back and sent late."""
    outbox, clock = subscribed(throttle_ms=100)
    outbox.offer("/scan", "m0")
    assert drain(outbox, loop) == ["m0"]
    clock.now += 0.05
    outbox.offer("/scan", "m1")
    clock.now += 0.06
    assert drain(outbox, loop) == []
    outbox.offer("/scan", "m2")
    assert drain(outbox, loop) == ["m2"]


def test_replies_go_first_and_a_client_that_lets_them_pile_up_is_told(loop):
    outbox, _ = subscribed()
    outbox.offer("/scan", "m0")
    assert all(outbox.reply(f"r{n}") for n in range(4))
    assert not outbox.reply("r4")  # max_replies is 4: the server closes such a client
    assert drain(outbox, loop) == ["r0", "r1", "r2", "r3", "m0"]


def test_messages_of_several_topics_go_oldest_first_and_unsubscribed_ones_are_not_kept(loop):
    outbox, _ = subscribed(queue_length=2)
    outbox.outlets["/odom"] = Outlet(0, 2)
    for frame, topic in [("s0", "/scan"), ("o0", "/odom"), ("x0", "/camera"), ("s1", "/scan"), ("o1", "/odom")]:
        outbox.offer(topic, frame)
    assert drain(outbox, loop) == ["s0", "o0", "s1", "o1"]


def test_new_settings_keep_the_newest_messages_that_fit():
    outlet = Outlet(0, 5)
    for n in range(5):
        outlet.offer(n, f"m{n}", 0.0)
    outlet.configure(0, 2)
    assert [frame for _, frame in outlet.pending] == ["m3", "m4"]
