"""A fake OpenAI-compatible chat-completions server on 127.0.0.1, for tests and the benchmark.

It records every request (path, headers, JSON body) and answers from a queue of behaviours,
falling back to ``default`` when the queue is empty::

    server.push(Reply("```json\\n{...}\\n```"), Status(429, retry_after=0), Hang(5.0))

HTTP/1.1 keep-alive with Nagle off: otherwise every call through the openai SDK pays ~40 ms of
delayed-ACK latency and timings mean nothing.
"""

from __future__ import annotations

import json
import socket
import threading
from collections import deque
from dataclasses import dataclass, field
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any, Callable


@dataclass
class Reply:
    """Answer 200 with ``text`` as the assistant's content (a callable gets the request body)."""

    text: str | Callable[[dict[str, Any]], str]
    finish_reason: str = "stop"
    usage: tuple[int, int] = (1000, 150)


@dataclass
class Status:
    """Answer with an HTTP error status and an OpenAI-style error body."""

    code: int
    message: str = "fake server error"
    retry_after: float | None = None


@dataclass
class Hang:
    """Wait ``seconds`` before answering (longer than the client's timeout)."""

    seconds: float
    then: Reply = field(default_factory=lambda: Reply("{}"))


@dataclass
class Recorded:
    path: str
    headers: dict[str, str]
    body: dict[str, Any]


class FakeOpenAI:
    """The server; ``url`` is the ``api_base`` to give a backend."""

    def __init__(self, default: Reply | Status | Hang | None = None) -> None:
        self.default = default or Reply("{}")
        self.queue: deque = deque()
        self.requests: list[Recorded] = []
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._server = ThreadingHTTPServer(("127.0.0.1", 0), self._handler())
        self._server.daemon_threads = True
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self._server.server_address[1]}/v1"

    def push(self, *behaviours: Reply | Status | Hang) -> None:
        self.queue.extend(behaviours)

    def start(self) -> "FakeOpenAI":
        self._thread.start()
        return self

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._server.shutdown()
        self._server.server_close()

    def __enter__(self) -> "FakeOpenAI":
        return self.start()

    def __exit__(self, *exc: Any) -> None:
        self.stop()

    def _next(self, body: dict[str, Any]) -> Reply | Status | Hang:
        with self._lock:
            return self.queue.popleft() if self.queue else self.default

    def _handler(self) -> type[BaseHTTPRequestHandler]:
        fake = self

        class Handler(BaseHTTPRequestHandler):
            protocol_version = "HTTP/1.1"

            def setup(self) -> None:
                super().setup()
                self.connection.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

            def log_message(self, format: str, *args: Any) -> None:  # quiet
                pass

            def _send(self, code: int, payload: dict[str, Any], headers: dict[str, str] | None = None) -> None:
                data = json.dumps(payload).encode()
                self.send_response(code)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(len(data)))
                for key, value in (headers or {}).items():
                    self.send_header(key, value)
                self.end_headers()
                self.wfile.write(data)

            def do_POST(self) -> None:
                length = int(self.headers.get("Content-Length", "0"))
                raw = self.rfile.read(length)
                try:
                    body = json.loads(raw or b"{}")
                except json.JSONDecodeError:
                    body = {"_unparsed": raw.decode("utf-8", "replace")}
                fake.requests.append(Recorded(self.path, {k.lower(): v for k, v in self.headers.items()}, body))
                behaviour = fake._next(body)
                try:
                    if isinstance(behaviour, Hang):
                        if fake._stop.wait(behaviour.seconds):
                            return
                        behaviour = behaviour.then
                    if isinstance(behaviour, Status):
                        headers = {} if behaviour.retry_after is None else {"Retry-After": f"{behaviour.retry_after:g}"}
                        self._send(behaviour.code, {"error": {"message": behaviour.message, "type": "fake_error",
                                                              "code": behaviour.code}}, headers)
                        return
                    text = behaviour.text(body) if callable(behaviour.text) else behaviour.text
                    prompt, completion = behaviour.usage
                    self._send(200, {
                        "id": f"chatcmpl-{len(fake.requests)}", "object": "chat.completion", "created": 0,
                        "model": body.get("model", "fake"),
                        "choices": [{"index": 0, "message": {"role": "assistant", "content": text},
                                     "finish_reason": behaviour.finish_reason}],
                        "usage": {"prompt_tokens": prompt, "completion_tokens": completion,
                                  "total_tokens": prompt + completion},
                    })
                except (BrokenPipeError, ConnectionResetError):
                    pass

        return Handler
