"""One pace per provider and model, shared by every trial of a worker process.

A run with many trials in flight (``ablate --concurrency``) must not fire them all at a paid API
at once and then fail them all on the 429s it provoked. Every call of the litellm backends first
asks the process's :class:`RateLimiter` for its model and server when it may go:

* ``requests_per_minute``: calls are spaced 60/rpm seconds apart;
* ``tokens_per_minute``: each answer's tokens push the next call back by tokens × 60/tpm;
* a 429 holds *every* call to that model back for its ``Retry-After`` (capped by the backend's
  ``backoff_max_s``), not only the call that met it;
* after a 429, one call goes first -- the *probe* -- and the others wait for what it meets: an
  answer (or any failure that is not a 429) lets them all go; another 429 holds them again. A
  burst that outlasts one ``Retry-After`` thus costs one call per hold, not one per trial in
  flight (measured: four trials at once sent four calls after each hold before).

Limits are per worker process: with ``--workers N`` each process paces at 1/N of the configured
rate (the share is set by the executor, ``SAFEEMBODAI_RATE_SHARE``). A limiter keeps no history
across runs and reads nothing from the server but its 429s.
"""

from __future__ import annotations

import os
import threading
import time
from typing import Callable

#: How often a call waiting for the probe checks that the probe's thread is still alive (seconds).
PROBE_CHECK_S = 1.0

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
        self._lock = threading.Condition()
        self._next_request = 0.0
        self._tokens_free_at = 0.0
        self._held_until = 0.0
        self._recovering = False  # a 429 was met and no call has been answered since
        self._probe: threading.Thread | None = None  # the one call out while recovering

    def reserve(self, requests_per_minute: float | None) -> float:
        """Reserve the next call's start; return how long to wait before it (0 when it may go now).
        After a 429 the first caller becomes the probe and the others block here until it
        settles (:meth:`settle`; or until its thread is gone)."""
        me = threading.current_thread()
        with self._lock:
            while self._recovering and self._probe not in (None, me):
                if not self._probe.is_alive():  # the probe's trial died without settling
                    self._probe = None
                    break
                self._lock.wait(timeout=PROBE_CHECK_S)
            if self._recovering:
                self._probe = me
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
        """A 429: no call to this model starts for ``seconds`` from now, and the next goes alone."""
        with self._lock:
            self._held_until = max(self._held_until, self._clock() + seconds)
            self._recovering = True

    @property
    def recovering(self) -> bool:
        """A 429 was met and no call has been answered since: a call now waits for the probe."""
        return self._recovering

    def settle(self, answered: bool) -> None:
        """A call of this thread is over: if it was the probe, an answer (``answered``; or a failure
        that is not the provider's limit) ends the recovery and lets every waiting call go; anything
        else -- a 429 (already :meth:`hold`), a give-up, an interrupt -- passes the probe to the
        next caller, which goes alone."""
        with self._lock:
            if self._probe is not threading.current_thread():
                return
            self._probe = None
            if answered:
                self._recovering = False
            self._lock.notify_all()


def limiter_for(server: str, model: str) -> RateLimiter:
    """The process's limiter of ``model`` on ``server`` (made on first use)."""
    with _lock:
        return _limiters.setdefault((server, model), RateLimiter())
