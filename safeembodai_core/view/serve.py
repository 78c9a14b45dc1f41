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
import os
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any, BinaryIO, Callable, cast
from urllib.parse import quote, unquote

from ..errors import SafeEmbodAIError
from ..logs import get_logger
from ..runs.files import open_inside
from .html import CSP_HEADER
from .rerun_viewer import VIEWER_PREFIX, viewer_url

log = get_logger(__name__)

#: seconds a connection may stay silent (its request line, a header, between requests) before it is closed
REQUEST_TIMEOUT_S = 10.0
#: connections served at once; one more is closed unanswered until one ends (a client opening hundreds of
#: silent connections, a slow loris, cannot hold a thread each)
MAX_CONNECTIONS = 32


class _BoundedServer(ThreadingHTTPServer):
    """A thread per connection, at most :data:`MAX_CONNECTIONS` at once."""

    daemon_threads = True

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.slots = threading.BoundedSemaphore(MAX_CONNECTIONS)

    def process_request(self, request: Any, client_address: Any) -> None:
        if not self.slots.acquire(blocking=False):
            log.warning("view.serve_busy", client=str(client_address[0]), most=MAX_CONNECTIONS)
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self.slots.release()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self.slots.release()


class _Handler(SimpleHTTPRequestHandler):
    """Serves the site's own files only, each opened once and served as opened: a regular file reached
    from the site folder with no symlink anywhere (:func:`~safeembodai_core.runs.files.open_inside`), never
    a FIFO or a device, no folder listing, no dot-file (a page being written); only a path as the request
    target (no ``http://host/...``), and only to requests addressed to this server (a ``Host`` header
    naming another host is refused: no DNS rebinding onto it). A malformed request line is answered by
    http.server's own error (400, 414, 505), with its status line (never an HTTP/0.9 answer: a request
    saying ``HTTP/0.9`` is a 505)."""

    allowed_hosts: frozenset[str] = frozenset()
    viewer_port: int | None = None  # Rerun's web viewer's port, when it is served
    viewer_origins: frozenset[str] = frozenset()  # the origins it is reached at: they may read .rrd files
    cors_origin: str | None = None  # this request's: answered with Access-Control-Allow-Origin
    vary_origin = False  # this request's: a recording, whose answer depends on the Origin
    default_request_version = "HTTP/1.0"  # a line without a version is answered with a status line too
    timeout = REQUEST_TIMEOUT_S  # the socket's: a silent client is closed, not waited on
    raw_requestline: bytes  # http.server's, read by handle_one_request (typeshed leaves it out)

    def handle_one_request(self) -> None:
        self.cors_origin, self.vary_origin = None, False  # set per request; a malformed one sets neither
        super().handle_one_request()

    def parse_request(self) -> bool:
        # http.server answers a request line ending in HTTP/0.9 with the body alone: no status line and no
        # header (no CSP, no nosniff), its errors (431) included
        words = str(self.raw_requestline, "iso-8859-1").rstrip("\r\n").split()
        if len(words) >= 3 and words[-1] == "HTTP/0.9":
            self.command, self.requestline = "", " ".join(words)
            self.request_version, self.close_connection = self.default_request_version, True
            self.send_error(505, "HTTP/0.9 is not served")
            return False
        return super().parse_request()

    def send_head(self) -> BinaryIO | None:
        host = (self.headers.get("Host") or "").lower()
        if host not in self.allowed_hosts:
            self.send_error(421, "Misdirected Request")
            return None
        asked = _asked_path(self.path)
        if asked is None:
            self.send_error(400, "Bad request target: a path only (no scheme, host or control characters)")
            return None
        if asked == "/":  # the address `view --serve` prints without its page: the index
            self._redirect("/index.html")
            return None
        if asked.startswith(VIEWER_PREFIX):
            self._to_viewer(host, asked[len(VIEWER_PREFIX) - 1:])
            return None
        opened = self._site_file(asked)
        if opened is None:
            self.send_error(404, "File not found")
            return None
        fd, info = opened
        if asked.endswith(".rrd"):
            origin = self.headers.get("Origin")
            self.cors_origin = origin if origin in self.viewer_origins else None
            self.vary_origin = True
        try:
            self.send_response(200)
            self.send_header("Content-Type", self.guess_type(asked))
            self.send_header("Content-Length", str(info.st_size))
            self.send_header("Last-Modified", self.date_time_string(int(info.st_mtime)))
            self.end_headers()
            return os.fdopen(fd, "rb")
        except BaseException:
            os.close(fd)
            raise

    def _site_file(self, asked: str) -> tuple[int, os.stat_result] | None:
        return open_site_file(Path(self.directory), asked)

    def _redirect(self, location: str) -> None:
        self.send_response(302)
        self.send_header("Location", location)
        self.send_header("Content-Length", "0")
        self.end_headers()

    def _to_viewer(self, host: str, asked: str) -> None:
        """A redirect to Rerun's web viewer opening the recording ``asked`` (a decoded URL path of this
        site), at the address the browser used (so the viewer's origin is one of :attr:`viewer_origins`)."""
        if self.viewer_port is None:
            self.send_error(404, "Rerun's web viewer is not served here")
            return
        opened = self._site_file(asked) if asked.endswith(".rrd") else None
        if opened is None:
            self.send_error(404, "File not found")
            return
        os.close(opened[0])
        recording = f"http://{host}{quote(asked)}"
        self._redirect(viewer_url(host.rsplit(":", 1)[0], self.viewer_port, recording))

    def end_headers(self) -> None:
        self.send_header("Content-Security-Policy", CSP_HEADER)
        self.send_header("X-Content-Type-Options", "nosniff")
        self.send_header("Referrer-Policy", "no-referrer")
        self.send_header("Cache-Control", "no-cache")
        if self.cors_origin is not None:
            self.send_header("Access-Control-Allow-Origin", self.cors_origin)
        if self.vary_origin:
            self.send_header("Vary", "Origin")
        super().end_headers()

    def log_message(self, format: str, *args: Any) -> None:  # structlog, not stderr lines
        log.debug("view.request", request=format % args)


def _asked_path(target: str) -> str | None:
    """The decoded path of a request target, without its query; None unless the target is a path
    (origin-form: ``/...``; not ``http://host/...``, ``host:port`` or ``*``), in UTF-8, with no control
    character (a NUL included) once decoded."""
    if not target.startswith("/") or target.startswith("//"):
        return None
    try:
        asked = unquote(target.split("?", 1)[0].split("#", 1)[0], errors="strict")
    except UnicodeDecodeError:
        return None
    if any(ord(char) < 0x20 or ord(char) == 0x7F for char in asked):
        return None
    return asked


def open_site_file(root: Path, asked: str) -> tuple[int, os.stat_result] | None:
    """The file of the site in ``root`` at the decoded URL path ``asked`` (:func:`_asked_path`), opened
    (a descriptor and its status), or None: not there, a folder, a dot part, a backslash, a symlink
    anywhere in the site, not a regular file. What it opens is what is served."""
    parts = asked.split("/")[1:]
    if not parts or any(not part or part.startswith(".") or "\\" in part for part in parts):
        return None
    try:
        return open_inside(root, root.joinpath(*parts))
    except (OSError, SafeEmbodAIError):
        return None


class SiteServer:
    """The site in ``folder`` served on ``host:port`` (port 0: any free one), rebuilt by ``rebuild``;
    ``viewer_port``: the port Rerun's web viewer is served on (:func:`.rerun_viewer.start_web_viewer`),
    for the redirects to it and the recordings it reads."""

    def __init__(self, folder: Path, rebuild: Callable[[], Any], host: str = "127.0.0.1", port: int = 8000,
                 interval_s: float = 2.0, viewer_port: int | None = None) -> None:
        handler = cast("type[_Handler]", type("SiteHandler", (_Handler,), {}))
        self.httpd = _BoundedServer((host, port), functools.partial(handler, directory=str(folder)))
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
