"""A fake OpenAI-compatible chat-completions server on 127.0.0.1, for tests and the benchmark.

It records every request (path, headers, JSON body) and answers from a queue of behaviours,
falling back to ``default`` when the queue is empty::

    server.push(Reply("```json\\n{...}\\n```"), Status(429, retry_after=0), Hang(5.0))

Besides honest replies it plays a hostile server: :class:`Trickle` keeps a response alive one
byte at a time (every read arrives within any per-read timeout), :class:`Raw` sends any body
with any status (a malformed 200 envelope, duplicate keys), :class:`Envelope` sends a
completion with any ``choices`` list and any other top-level fields (:func:`choice` builds one),
:class:`Redirect` answers with a 3xx and a ``Location``, ``Reply.usage`` may hold any JSON values,
and a callable ``Reply.text`` sees the request's headers (to reflect the ``Authorization``
header). Every request is recorded, GETs too (a client that follows a 302 sends one).

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
    """Answer 200 with ``text`` as the assistant's content (a callable gets the :class:`Recorded` request).

    ``finish_reason`` and the two ``usage`` counts are sent as given: any JSON value, even a
    string, a float or ``nan``.
    """

    text: str | Callable[["Recorded"], str]
    finish_reason: Any = "stop"
    usage: tuple[Any, Any] = (1000, 150)


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
class Trickle:
    """Send the status line and headers at once, then the body one byte every ``interval`` seconds.

    The body is ``then``'s JSON padded with leading spaces (valid JSON) so that the whole
    response takes about ``seconds``; each single read arrives well within a per-read timeout.
    """

    seconds: float
    interval: float = 0.1
    then: "Reply" = field(default_factory=lambda: Reply("{}"))


@dataclass
class Raw:
    """Answer ``code`` with ``body`` exactly as given (a malformed envelope, or not JSON at all)."""

    body: bytes | str
    code: int = 200
    content_type: str = "application/json"


@dataclass
class Redirect:
    """Answer ``code`` (301, 302, 303, 307, 308) with ``Location: location`` and a small JSON body."""

    code: int
    location: str


@dataclass
class Envelope:
    """Answer 200 with a chat completion whose ``choices`` are exactly ``choices`` (any JSON values);
    ``fields`` are set on (or, with the value ``DROP``, removed from) the top-level object."""

    choices: Any
    fields: dict[str, Any] = field(default_factory=dict)


#: the API key the tests put in ``SAFEEMBODAI_TEST_KEY`` (the ``fake_key`` fixture)
FAKE_KEY = "sk-fake-0123456789abcdefXYZ"

DROP = object()


def choice(text: Any, finish_reason: Any = "stop", index: Any = 0, **message: Any) -> dict[str, Any]:
    """One choice of an :class:`Envelope`: ``text`` as the content, ``message`` more message fields."""
    return {"index": index, "message": {"role": "assistant", "content": text, **message},
            "finish_reason": finish_reason}


@dataclass
class Recorded:
    path: str
    headers: dict[str, str]
    body: dict[str, Any]
    method: str = "POST"


Behaviour = Reply | Status | Hang | Trickle | Raw | Redirect | Envelope


class FakeOpenAI:
    """The server; ``url`` is the ``api_base`` to give a backend."""

    def __init__(self, default: Behaviour | None = None) -> None:
        self.default = default or Reply("{}")
        self.queue: deque = deque()
        self.requests: list[Recorded] = []
        self.in_flight = self.peak_in_flight = 0  # requests being answered now, and the most at once
        self.arrivals: list[int] = []  # per request, how many others were being answered when it came
        self._stop = threading.Event()
        self._lock = threading.Lock()
        self._server = ThreadingHTTPServer(("127.0.0.1", 0), self._handler())
        self._server.daemon_threads = True
        self._thread = threading.Thread(target=self._server.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True)

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self._server.server_address[1]}/v1"

    def push(self, *behaviours: Behaviour) -> None:
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

    def _next(self, body: dict[str, Any]) -> Behaviour:
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

            def _send_bytes(self, code: int, data: bytes, headers: dict[str, str] | None = None,
                            content_type: str = "application/json") -> None:
                self.send_response(code)
                self.send_header("Content-Type", content_type)
                self.send_header("Content-Length", str(len(data)))
                for key, value in (headers or {}).items():
                    self.send_header(key, value)
                self.end_headers()
                self.wfile.write(data)

            def _trickle(self, seconds: float, interval: float, data: bytes) -> None:
                padding = max(1, int(seconds / interval))
                self.send_response(200)
                self.send_header("Content-Type", "application/json")
                self.send_header("Content-Length", str(padding + len(data)))
                self.end_headers()
                self.wfile.flush()
                for _ in range(padding):
                    self.wfile.write(b" ")
                    self.wfile.flush()
                    if fake._stop.wait(interval):
                        return
                self.wfile.write(data)

            def do_GET(self) -> None:
                self.do_POST()

            def do_POST(self) -> None:
                length = int(self.headers.get("Content-Length", "0"))
                raw = self.rfile.read(length)
                try:
                    body = json.loads(raw or b"{}")
                except json.JSONDecodeError:
                    body = {"_unparsed": raw.decode("utf-8", "replace")}
                request = Recorded(self.path, {k.lower(): v for k, v in self.headers.items()}, body, self.command)
                fake.requests.append(request)
                behaviour = fake._next(body)
                with fake._lock:
                    fake.arrivals.append(fake.in_flight)
                    fake.in_flight += 1
                    fake.peak_in_flight = max(fake.peak_in_flight, fake.in_flight)
                try:
                    if isinstance(behaviour, Hang):
                        if fake._stop.wait(behaviour.seconds):
                            return
                        behaviour = behaviour.then
                    if isinstance(behaviour, Status):
                        headers = {} if behaviour.retry_after is None else {"Retry-After": f"{behaviour.retry_after:g}"}
                        error = {"error": {"message": behaviour.message, "type": "fake_error", "code": behaviour.code}}
                        self._send_bytes(behaviour.code, json.dumps(error).encode(), headers)
                        return
                    if isinstance(behaviour, Raw):
                        data = behaviour.body.encode() if isinstance(behaviour.body, str) else behaviour.body
                        self._send_bytes(behaviour.code, data, content_type=behaviour.content_type)
                        return
                    if isinstance(behaviour, Redirect):
                        data = json.dumps({"moved": behaviour.location}).encode()
                        self._send_bytes(behaviour.code, data, {"Location": behaviour.location})
                        return
                    if isinstance(behaviour, Envelope):
                        data = json.dumps(_envelope(behaviour, request, len(fake.requests))).encode()
                        self._send_bytes(200, data)
                        return
                    trickle = behaviour if isinstance(behaviour, Trickle) else None
                    reply = behaviour.then if trickle else behaviour
                    data = json.dumps(_completion(reply, request, len(fake.requests))).encode()
                    if trickle:
                        self._trickle(trickle.seconds, trickle.interval, data)
                    else:
                        self._send_bytes(200, data)
                except (BrokenPipeError, ConnectionResetError):
                    pass
                finally:
                    with fake._lock:
                        fake.in_flight -= 1

        return Handler


def _completion(reply: Reply, request: Recorded, number: int) -> dict[str, Any]:
    text = reply.text(request) if callable(reply.text) else reply.text
    prompt, completion = reply.usage
    both_ints = all(type(n) is int for n in reply.usage)
    return {
        "id": f"chatcmpl-{number}", "object": "chat.completion", "created": 0,
        "model": request.body.get("model", "fake"),
        "choices": [{"index": 0, "message": {"role": "assistant", "content": text},
                     "finish_reason": reply.finish_reason}],
        "usage": {"prompt_tokens": prompt, "completion_tokens": completion,
                  "total_tokens": prompt + completion if both_ints else 0},
    }


def _envelope(envelope: Envelope, request: Recorded, number: int) -> dict[str, Any]:
    body = _completion(Reply(""), request, number)
    body["choices"] = envelope.choices
    for key, value in envelope.fields.items():
        if value is DROP:
            body.pop(key, None)
        else:
            body[key] = value
    return body
