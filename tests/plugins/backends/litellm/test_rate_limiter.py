"""The pace of calls to one model (``plugins/backends/litellm/limiter.py``), on a fake clock."""

from __future__ import annotations

import pytest

from safeembodai_plugins.backends.litellm.limiter import RateLimiter


class Clock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_requests_per_minute_spaces_reservations_and_a_hold_delays_every_one():
    clock = Clock()
    limiter = RateLimiter(clock)
    assert [limiter.reserve(120) for _ in range(3)] == [0.0, 0.5, 1.0]  # 0.5 s apart
    clock.now += 1.0
    assert limiter.reserve(120) == pytest.approx(0.5)
    limiter.hold(10.0)  # a 429 asked for 10 s: the next call of any trial waits it out
    assert limiter.reserve(None) == pytest.approx(10.0)


def test_tokens_per_minute_pushes_the_next_call_back_by_what_answers_used():
    clock = Clock()
    limiter = RateLimiter(clock)
    limiter.spent(3000, tokens_per_minute=60_000)  # 3000 tokens at 1000/s: 3 s
    assert limiter.reserve(None) == pytest.approx(3.0)
    limiter.spent(0, tokens_per_minute=60_000)
    limiter.spent(500, tokens_per_minute=None)  # no limit: nothing owed
    clock.now += 5.0
    assert limiter.reserve(None) == 0.0


def test_worker_processes_split_the_rate(monkeypatch):
    monkeypatch.setenv("SAFEEMBODAI_RATE_SHARE", "4")
    limiter = RateLimiter(Clock())
    assert [limiter.reserve(240) for _ in range(2)] == [0.0, 1.0]  # 240/min over 4 workers: 1 s apart each
    monkeypatch.setenv("SAFEEMBODAI_RATE_SHARE", "nonsense")
    assert RateLimiter(Clock()).reserve(60) == 0.0  # an unreadable share counts as 1
