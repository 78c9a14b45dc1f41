"""One ``litellm.completion`` call bounded by a deadline for the *whole* call.

httpx, under litellm and the openai SDK, applies its timeout to each socket operation: a server
that sends one byte every half second keeps a call alive for as long as it likes, whatever the
timeout (encode/httpx#1450, still open; neither litellm nor the openai SDK offers a total
deadline for a non-streaming call, and cancelling an asyncio task would tie every call to an
event loop that litellm caches its clients on). So the call runs in a worker thread and the
caller waits for it until the deadline, then raises :class:`CallTimedOut` and walks away.

The trade-off: a Python thread cannot be stopped. An abandoned worker runs on until the server
finishes or goes quiet for one per-read timeout, and then its result -- answer or error -- is
dropped: it lands in a list only the departed caller could read. A worker that finishes after
the deadline is treated as abandoned even if the caller had not yet looked. At most
:data:`MAX_ABANDONED` abandoned workers may be alive in the process at once; while that many
are still held open by a server, new calls are refused (:class:`TooManyHungCalls`) rather than
piling up threads and sockets without bound.
"""

from __future__ import annotations

import contextvars
import threading
import time
import warnings
from typing import Any, Callable

MAX_ABANDONED = 8

_lock = threading.Lock()
_abandoned: list[threading.Thread] = []


class CallTimedOut(TimeoutError):
    """The call did not complete within its deadline; its answer, if any comes, is never used."""

    def __init__(self, deadline_s: float) -> None:
        super().__init__(f"no complete answer within {deadline_s:g} s; the call was abandoned")


class TooManyHungCalls(RuntimeError):
    """Too many earlier calls are still held open past their deadline to start another."""

    def __init__(self, alive: int) -> None:
        super().__init__(f"{alive} earlier calls are still held open by the server past their deadline; "
                         "not starting another")


def quiet_pydantic_serializer_warnings() -> None:
    """Drop pydantic's serializer warnings, which litellm's response objects raise on odd replies.

    Their text quotes fragments of the (hostile) answer and would reach stderr. A narrow filter
    -- UserWarning, issued from ``pydantic.main``, starting "Pydantic serializer warnings" -- is
    (re)inserted at the front of the process-wide list rather than wrapped around the call with
    ``warnings.catch_warnings``, which swaps that list without a lock: with the call in a worker
    thread, and abandoned workers outliving their callers, restoring it would race other threads.
    ``filterwarnings`` replaces an identical entry, so the list does not grow.
    """
    warnings.filterwarnings("ignore", message="Pydantic serializer warnings", category=UserWarning,
                            module=r"pydantic\.main")


def abandoned_alive() -> int:
    """How many abandoned calls are still running (for tests and diagnostics)."""
    with _lock:
        _abandoned[:] = [worker for worker in _abandoned if worker.is_alive()]
        return len(_abandoned)


def call_with_deadline(function: Callable[..., Any], kwargs: dict[str, Any], deadline_s: float) -> Any:
    """``function(**kwargs)`` if it returns or raises within ``deadline_s`` seconds, else :class:`CallTimedOut`."""
    alive = abandoned_alive()
    if alive >= MAX_ABANDONED:
        raise TooManyHungCalls(alive)
    quiet_pydantic_serializer_warnings()
    outcome: list[tuple[bool, Any, float]] = []
    context = contextvars.copy_context()

    def work() -> None:
        try:
            result = (True, context.run(function, **kwargs))
        except BaseException as error:  # handed to the caller, who re-raises it
            result = (False, error)
        outcome.append((*result, time.monotonic()))

    deadline = time.monotonic() + deadline_s
    worker = threading.Thread(target=work, name="safeembodai-llm-call", daemon=True)
    worker.start()
    worker.join(deadline_s)
    if worker.is_alive() or not outcome or outcome[0][2] > deadline:
        with _lock:
            _abandoned.append(worker)
        raise CallTimedOut(deadline_s)
    ok, value, _ = outcome[0]
    if ok:
        return value
    raise value
