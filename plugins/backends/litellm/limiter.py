"""One pace per provider and model, shared by every trial of a worker process.

A run with many trials in flight (``ablate --concurrency``) must not fire them all at a paid API
at once and then fail them all on the 429s it provoked. Every call of the litellm backends first
asks the process's :class:`RateLimiter` for its model and server when it may go:

* ``requests_per_minute``: calls are spaced 60/rpm seconds apart;
* ``tokens_per_minute``: each answer's tokens push the next call back by tokens × 60/tpm;
* a 429 holds *every* call to that model back for its ``Retry-After`` (capped by the backend's
  ``backoff_max_s``), not only the call that met it.

Limits are per worker process: with ``--workers N`` each process paces at 1/N of the configured
rate (the share is set by the executor, ``SAFEEMBODAI_RATE_SHARE``). A limiter keeps no history
across runs and reads nothing from the server but its 429s.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Callable

_lock = threading.Lock()
_limiters: dict[tuple[str, str], "RateLimiter"] = {}


def share() -> int:
    """How many worker processes split the configured rates (1 unless the executor says otherwise)."""
    try:
        return max(1, int(os.environ.get("SAFEEMBODAI_RATE_SHARE", "1")))
    except ValueError:
        return 1


class RateLimiter:
    """When the next call to one model on one server may start (see the module docstring)."""

    def __init__(self, clock: Callable[[], float] = time.monotonic) -> None:
        self._clock = clock
        self._lock = threading.Lock()
        self._next_request = 0.0
        self._tokens_free_at = 0.0
        self._held_until = 0.0

    def reserve(self, requests_per_minute: float | None) -> float:
        """Reserve the next call's start; return how long to wait before it (0 when it may go now)."""
        with self._lock:
            now = self._clock()
            start = max(now, self._held_until, self._tokens_free_at)
            if requests_per_minute:
                start = max(start, self._next_request)
                self._next_request = start + 60.0 * share() / requests_per_minute
            return start - now

    def spent(self, tokens: int, tokens_per_minute: int | None) -> None:
        """An answer used ``tokens``: with a tokens-per-minute limit, later calls wait their share."""
        if not tokens_per_minute or tokens <= 0:
            return
        with self._lock:
            owed = tokens * 60.0 * share() / tokens_per_minute
            self._tokens_free_at = max(self._clock(), self._tokens_free_at) + owed

    def hold(self, seconds: float) -> None:
        """A 429: no call to this model starts for ``seconds`` from now."""
        with self._lock:
            self._held_until = max(self._held_until, self._clock() + seconds)


def limiter_for(server: str, model: str) -> RateLimiter:
    """The process's limiter of ``model`` on ``server`` (made on first use)."""
    with _lock:
        return _limiters.setdefault((server, model), RateLimiter())
