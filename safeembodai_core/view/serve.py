"""``view --serve``: the site on a local HTTP server, rebuilt while runs are written.

The server serves only the site folder, with the Content-Security-Policy as a header too and
``nosniff``; a background thread rebuilds the site every ``interval_s`` seconds (incrementally:
only changed runs), and the pages ask the browser to reload every ``refresh`` seconds. With
Rerun's web viewer served beside it (``viewer_port``, :mod:`.rerun_viewer`), ``/rerun-viewer/<a
recording's path>`` redirects to the viewer opening that recording, and a ``.rrd`` answers the
viewer's origin (only it, only for ``.rrd``) with a CORS header so the viewer may read it.
"""

from __future__ import annotations

import functools
import io
import os
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, BinaryIO, Callable, cast
from urllib.parse import quote, unquote, urlsplit

from ..logs import get_logger
from .html import CSP_HEADER
from .rerun_viewer import VIEWER_PREFIX, viewer_url

log = get_logger(__name__)


class _Handler(SimpleHTTPRequestHandler):
    """Serves the site's own files only: nothing a symlink in it points to outside it, no folder
    listing, no dot-file (a page being written), and only to requests addressed to this server
    (a ``Host`` header naming another host is refused: no DNS rebinding onto it)."""

    allowed_hosts: frozenset[str] = frozenset()
    viewer_port: int | None = None  # Rerun's web viewer's port, when it is served
    viewer_origins: frozenset[str] = frozenset()  # the origins it is reached at: they may read .rrd files
    cors_origin: str | None = None  # this request's: answered with Access-Control-Allow-Origin

    def send_head(self) -> io.BytesIO | BinaryIO | None:
        self.cors_origin = None
        host = (self.headers.get("Host") or "").lower()
        if host not in self.allowed_hosts:
            self.send_error(421, "Misdirected Request")
            return None
        raw = urlsplit(self.path).path
        asked = unquote(raw)
        if asked == "/":  # the address `view --serve` prints without its page: the index
            self._redirect("/index.html")
            return None
        if asked.startswith(VIEWER_PREFIX):
            self._to_viewer(host, "/" + raw[len(VIEWER_PREFIX):])
            return None
        if not self._in_site(raw):
            self.send_error(404, "File not found")
            return None
        if asked.endswith(".rrd"):
            origin = self.headers.get("Origin")
            self.cors_origin = origin if origin in self.viewer_origins else None
        return super().send_head()

    def _in_site(self, raw: str, exists: bool = False) -> bool:
        """The URL path ``raw`` may name a file of the site: inside it (no symlink out), no folder, no
        dot part (and, with ``exists``, a file that is there)."""
        root = Path(os.path.realpath(self.directory))
        real = Path(os.path.realpath(self.translate_path(raw)))
        return (root in real.parents and not real.is_dir() and (real.is_file() or not exists)
                and not any(part.startswith(".") for part in unquote(raw).split("/")))

    def _redirect(self, location: str) -> None:
        self.send_response(302)
        self.send_header("Location", location)
        self.send_header("Content-Length", "0")
        self.end_headers()

    def _to_viewer(self, host: str, raw: str) -> None:
        """A redirect to Rerun's web viewer opening the recording ``raw`` (a URL path of this site),
        at the address the browser used (so the viewer's origin is one of :attr:`viewer_origins`)."""
        if self.viewer_port is None:
            self.send_error(404, "Rerun's web viewer is not served here")
            return
        asked = unquote(raw)
        if not asked.endswith(".rrd") or not self._in_site(raw, exists=True):
            self.send_error(404, "File not found")
            return
        recording = f"http://{host}{quote(asked)}"
        self._redirect(viewer_url(host.rsplit(":", 1)[0], self.viewer_port, recording))

    def end_headers(self) -> None:
        self.send_header("Content-Security-Policy", CSP_HEADER)
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Cache-Control", "no-cache")
        if self.cors_origin is not None:
            self.send_header("Access-Control-Allow-Origin", self.cors_origin)
        if self.path.split("?", 1)[0].endswith(".rrd"):
            self.send_header("Vary", "Origin")
        super().end_headers()

    def log_message(self, format: str, *args: Any) -> None:  # structlog, not stderr lines
        log.debug("view.request", request=format % args)


class SiteServer:
    """The site in ``folder`` served on ``host:port`` (port 0: any free one), rebuilt by ``rebuild``;
    ``viewer_port``: the port Rerun's web viewer is served on (:func:`.rerun_viewer.start_web_viewer`),
    for the redirects to it and the recordings it reads."""

    def __init__(self, folder: Path, rebuild: Callable[[], Any], host: str = "127.0.0.1", port: int = 8000,
                 interval_s: float = 2.0, viewer_port: int | None = None) -> None:
        handler = cast("type[_Handler]", type("SiteHandler", (_Handler,), {}))
        self.httpd = ThreadingHTTPServer((host, port), functools.partial(handler, directory=str(folder)))
        bound_host, bound_port = self.httpd.server_address[:2]
        names = {host, str(bound_host)} | ({"localhost", "127.0.0.1", "[::1]"}
                                           if host in ("127.0.0.1", "localhost", "::1") else set())
        handler.allowed_hosts = frozenset(f"{name}:{bound_port}".lower() for name in names)
        if viewer_port is not None:
            handler.viewer_port = viewer_port
            handler.viewer_origins = frozenset(viewer_url(name.lower(), viewer_port, "").split("/?", 1)[0]
                                               for name in names)
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
