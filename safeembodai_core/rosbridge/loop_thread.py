"""An asyncio event loop in a daemon thread of its own: how the server and the client serve threads."""

from __future__ import annotations

import asyncio
import threading
from typing import Any, Callable, Coroutine, TypeVar

T = TypeVar("T")


class LoopThread:
    """Runs an event loop in a thread named ``name`` until :meth:`stop`; its tasks are cancelled then."""

    def __init__(self, name: str):
        self.loop = asyncio.new_event_loop()
        self.thread = threading.Thread(target=self._run, name=name, daemon=True)
        self.thread.start()

    def _run(self) -> None:
        asyncio.set_event_loop(self.loop)
        try:
            self.loop.run_forever()
        finally:
            tasks = asyncio.all_tasks(self.loop)
            for task in tasks:
                task.cancel()
            self.loop.run_until_complete(asyncio.gather(*tasks, return_exceptions=True))
            self.loop.run_until_complete(self.loop.shutdown_asyncgens())
            self.loop.close()

    def run(self, coroutine: Coroutine[Any, Any, T], timeout: float) -> T:
        """Run ``coroutine`` on the loop and wait for its result (``TimeoutError`` after ``timeout`` s)."""
        return asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(timeout)

    def call_soon(self, function: Callable[..., Any], *args: Any) -> bool:
        """Have the loop call ``function(*args)``; False when the loop has already closed."""
        try:
            self.loop.call_soon_threadsafe(function, *args)
        except RuntimeError:
            return False
        return True

    def inside(self) -> bool:
        """Whether the caller runs on the loop's own thread."""
        return threading.current_thread() is self.thread

    def stop(self, timeout: float) -> None:
        """Stop the loop and wait for the thread (not from the loop's own thread)."""
        if self.inside():
            raise RuntimeError("the loop's own thread cannot stop it")
        self.call_soon(self.loop.stop)
        self.thread.join(timeout)
