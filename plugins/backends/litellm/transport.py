"""The HTTP transport under the openai SDK: it records each exchange of a call and follows no redirect.

For routes litellm sends through the openai SDK (provider ``openai``: ``gpt-4o``, ``openai/<name>``
-- the ``gpt-4o`` and ``local`` backends) the backend hands litellm its own ``openai.OpenAI``
client, built once per backend (:func:`openai_client`), whose ``httpx.Client`` sends through a
:class:`RecordingTransport`. For the call that is running (:func:`recording`, a context variable:
:func:`~.litellm_call.call_with_deadline` runs the call in a worker thread with a copy of the
caller's context, so the worker's requests land in the caller's :class:`Recorder`) it keeps, for
each request: the server's origin (``scheme://host:port``, never a user or password), the status,
and the whole body as sent, decoded, read before the SDK or litellm see it -- at most
:data:`MAX_BODY_BYTES`; a longer body is refused, not read on. The backend reads its answer from
that body (:func:`safeembodai_core.models.chat_completion.reply_from_chat_completion`), not from
litellm's parsed object, and classifies failures from it (:mod:`.litellm_errors`).

Redirects: the client does not follow them (``follow_redirects=False``), the transport hands the
SDK a 3xx without its ``Location`` (so nothing can follow it) and records the Location's origin,
and it refuses to send a request to any origin but the configured server's, or any request of a
call after that call met a 3xx. A server that answers 307 never gets its prompt re-POSTed elsewhere.

Nothing here logs: no header (the key is one) is ever recorded; the body may reflect the key,
and the backend masks it before the body goes anywhere.
"""

from __future__ import annotations

import contextvars
import functools
import os
import ssl
import urllib.request
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any, Iterator, cast

import httpx

from safeembodai_core.models.chat_completion import MAX_BODY_BYTES

_DEFAULT_PORTS = {"http": 80, "https": 443}
_DROPPED_HEADERS = ("content-encoding", "content-length", "transfer-encoding", "location")


@dataclass
class Exchange:
    """One request of a call and what came back (``status`` None: no response was had)."""

    origin: str
    status: int | None = None
    body: bytes | None = None
    location: str | None = None  # the origin a 3xx pointed to (or "an unreadable location")
    refused: str | None = None  # why the transport did not send the request or did not read the body


@dataclass
class Recorder:
    """The exchanges of one call, in order."""

    exchanges: list[Exchange] = field(default_factory=list)

    @property
    def last(self) -> Exchange | None:
        return self.exchanges[-1] if self.exchanges else None

    def redirected(self) -> Exchange | None:
        """The first exchange answered with a 3xx, if any."""
        return next((e for e in self.exchanges if e.status is not None and 300 <= e.status < 400), None)


_current: contextvars.ContextVar[Recorder | None] = contextvars.ContextVar("safeembodai_llm_exchanges", default=None)


@contextmanager
def recording() -> Iterator[Recorder]:
    """A fresh :class:`Recorder` for the calls made inside the block (worker threads included)."""
    recorder = Recorder()
    token = _current.set(recorder)
    try:
        yield recorder
    finally:
        _current.reset(token)


class RefusedExchange(httpx.TransportError):
    """The transport did not send a request, or did not read its response (see ``Exchange.refused``)."""


def origin_of(url: Any) -> str:
    """``scheme://host:port`` of ``url`` (the default port written out; no user, password or path)."""
    parsed = url if isinstance(url, httpx.URL) else httpx.URL(str(url))
    scheme = parsed.scheme.lower()
    port = parsed.port or _DEFAULT_PORTS.get(scheme, 0)
    host = parsed.host
    if ":" in host:  # an IPv6 address
        host = f"[{host}]"
    return f"{scheme}://{host}:{port}"


def _location_origin(request: httpx.Request, location: str | None) -> str:
    if not location:
        return "no location"
    try:
        return origin_of(request.url.join(location))
    except Exception:  # a Location that is no URL
        return "an unreadable location"


class RecordingTransport(httpx.BaseTransport):
    """Sends through ``inner`` to ``allowed_origin`` only; records each exchange (module docstring)."""

    def __init__(self, allowed_origin: str, inner: httpx.BaseTransport | None = None,
                 max_body_bytes: int = MAX_BODY_BYTES) -> None:
        self.allowed_origin = allowed_origin
        self._inner = inner or httpx.HTTPTransport()
        self._max_body = max_body_bytes

    def __repr__(self) -> str:
        return f"RecordingTransport({self.allowed_origin!r})"

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        recorder = _current.get()
        earlier = recorder.redirected() if recorder is not None else None
        exchange = Exchange(origin_of(request.url))
        if recorder is not None:
            recorder.exchanges.append(exchange)
        if exchange.origin != self.allowed_origin:
            exchange.refused = f"a request to {exchange.origin}, not the configured server, was not sent"
        elif earlier is not None:
            exchange.refused = f"a request after an HTTP {earlier.status} redirect was not sent"
        if exchange.refused:
            raise RefusedExchange(exchange.refused, request=request)
        response = self._inner.handle_request(request)
        exchange.status = response.status_code
        headers = [(k, v) for k, v in response.headers.multi_items() if k.lower() not in _DROPPED_HEADERS]
        extensions = {k: v for k, v in response.extensions.items() if k in ("http_version", "reason_phrase")}
        if 300 <= response.status_code < 400:
            exchange.location = _location_origin(request, response.headers.get("location"))
            response.close()
            return httpx.Response(response.status_code, headers=headers, content=b"", request=request,
                                  extensions=extensions)
        exchange.body = self._read(request, response, exchange)
        return httpx.Response(response.status_code, headers=headers, content=exchange.body, request=request,
                              extensions=extensions)

    def _read(self, request: httpx.Request, response: httpx.Response, exchange: Exchange) -> bytes:
        """The whole body, decoded (gzip, ...), at most ``max_body_bytes``."""
        decoded = httpx.Response(response.status_code, headers=response.headers, stream=response.stream,
                                 request=request)
        chunks: list[bytes] = []
        size = 0
        try:
            for chunk in decoded.iter_bytes():
                size += len(chunk)
                if size > self._max_body:
                    exchange.refused = f"the reply's body is longer than {self._max_body} bytes; it was not read on"
                    raise RefusedExchange(exchange.refused, request=request)
                chunks.append(chunk)
        finally:
            decoded.close()
        return b"".join(chunks)

    def close(self) -> None:
        self._inner.close()


def _proxy_for(url: str) -> str | None:
    """The proxy the environment routes ``url`` through (as httpx would, were the transport its own)."""
    parsed = httpx.URL(url)
    proxies = urllib.request.getproxies()
    proxy = proxies.get(parsed.scheme) or proxies.get("all")
    if not proxy or not parsed.host or urllib.request.proxy_bypass(parsed.host):
        return None
    return proxy if "://" in proxy else f"http://{proxy}"


@functools.lru_cache(maxsize=4)
def _ssl_context(cert_file: str | None, cert_dir: str | None) -> ssl.SSLContext:
    """httpx's default verifying context for these ``SSL_CERT_FILE`` / ``SSL_CERT_DIR`` values, made
    once per process: loading the CA bundle takes ~50 ms, and every trial builds its own backend. An
    ``SSLContext`` is shared safely by threads and clients (each connection gets its own socket)."""
    return httpx.create_ssl_context()


def openai_client(base_url: str, api_key: str | None, timeout_s: float) -> Any:
    """An ``openai.OpenAI`` for ``base_url`` whose requests go through a :class:`RecordingTransport`."""
    import openai

    proxy = _proxy_for(base_url)
    verify = _ssl_context(os.environ.get("SSL_CERT_FILE"), os.environ.get("SSL_CERT_DIR"))
    transport = RecordingTransport(origin_of(base_url), httpx.HTTPTransport(verify=verify, proxy=proxy))
    http_client = httpx.Client(transport=transport, follow_redirects=False, timeout=timeout_s)
    # cast: openai 3.x annotates an httpx2.Client (1.x and 2.x an httpx.Client) and takes either
    return openai.OpenAI(api_key=api_key or "no-key-required", base_url=base_url, http_client=cast(Any, http_client),
                         max_retries=0, timeout=timeout_s)
