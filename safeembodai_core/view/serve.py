"""``view --serve``: the site on a local HTTP server, rebuilt while runs are written.

The server serves only the site folder, with the Content-Security-Policy as a header too and
``nosniff``; a background thread rebuilds the site every ``interval_s`` seconds (incrementally:
only changed runs), and the pages ask the browser to reload every ``refresh`` seconds.
"""

from __future__ import annotations

import functools
import io
import os
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, BinaryIO, Callable, cast
from urllib.parse import unquote, urlsplit

from ..logs import get_logger
from .html import CSP_HEADER

log = get_logger(__name__)


class _Handler(SimpleHTTPRequestHandler):
    """Serves the site's own files only: nothing a symlink in it points to outside it, no folder
    listing, no dot-file (a page being written), and only to requests addressed to this server
    (a ``Host`` header naming another host is refused: no DNS rebinding onto it)."""

    allowed_hosts: frozenset[str] = frozenset()

    def send_head(self) -> io.BytesIO | BinaryIO | None:
        host = (self.headers.get("Host") or "").lower()
        if host not in self.allowed_hosts:
            self.send_error(421, "Misdirected Request")
            return None
        asked = unquote(urlsplit(self.path).path)
        if asked == "/":  # the address `view --serve` prints without its page: the index
            self.send_response(302)
            self.send_header("Location", "/index.html")
            self.send_header("Content-Length", "0")
            self.end_headers()
            return None
        path = Path(self.translate_path(self.path))
        root = Path(os.path.realpath(self.directory))
        real = Path(os.path.realpath(path))
        if (root not in real.parents) or real.is_dir() or any(part.startswith(".") for part in asked.split("/")):
            self.send_error(404, "File not found")
            return None
        return super().send_head()

    def end_headers(self) -> None:
        self.send_header("Content-Security-Policy", CSP_HEADER)
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Cache-Control", "no-cache")
        super().end_headers()

    def log_message(self, format: str, *args: Any) -> None:  # structlog, not stderr lines
        log.debug("view.request", request=format % args)


class SiteServer:
    """The site in ``folder`` served on ``host:port`` (port 0: any free one), rebuilt by ``rebuild``."""

    def __init__(self, folder: Path, rebuild: Callable[[], Any], host: str = "127.0.0.1", port: int = 8000,
                 interval_s: float = 2.0) -> None:
        handler = cast("type[_Handler]", type("SiteHandler", (_Handler,), {}))
        self.httpd = ThreadingHTTPServer((host, port), functools.partial(handler, directory=str(folder)))
        bound_host, bound_port = self.httpd.server_address[:2]
        names = {host, str(bound_host)} | ({"localhost", "127.0.0.1", "[::1]"}
                                           if host in ("127.0.0.1", "localhost", "::1") else set())
        handler.allowed_hosts = frozenset(f"{name}:{bound_port}".lower() for name in names)
        self.rebuild, self.interval_s = rebuild, interval_s
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []

    @property
    def url(self) -> str:
        host, port = self.httpd.server_address[:2]
        return f"http://{str(host)}:{port}/index.html"  # a bound AF_INET(6) host is text

    def start(self) -> "SiteServer":
        for target in (self.httpd.serve_forever, self._watch):
            thread = threading.Thread(target=target, daemon=True)
            thread.start()
            self._threads.append(thread)
        return self

    def _watch(self) -> None:
        while not self._stop.wait(self.interval_s):
            try:
                self.rebuild()
            except Exception as error:  # a bad moment (a run being created): try again next time
                log.warning("view.rebuild_failed", error=str(error))

    def stop(self) -> None:
        self._stop.set()
        self.httpd.shutdown()
        self.httpd.server_close()
