"""Rerun's web viewer beside ``view --serve --rerun-viewer``: the viewer inside the ``rerun-sdk`` wheel.

``rerun.serve_web_viewer`` serves the viewer's own HTML, JS and Wasm over HTTP -- no gRPC server,
no data -- on a port of its own. It listens on every interface, ``0.0.0.0``: its parameters are the
port, whether to open a browser and a server to connect to, and rerun-sdk's bindings (0.41) build the
rest of their ``WebViewerConfig`` from its defaults, whose ``bind_ip`` is ``0.0.0.0`` (the ``rerun`` CLI's
``--bind`` serves a gRPC server beside it). So it is served only when asked (``--rerun-viewer``), with a
warning; it runs until the process ends. The viewer opens the recording named by
its ``url`` query parameter (``http://HOST:PORT/?url=...``) and fetches it from the site's server,
which lets the viewer's origin, and only it, read ``.rrd`` files (:mod:`.serve`).

A served trial page links to ``/rerun-viewer/<the recording's path in the site>`` on the site's own
server, which answers with a redirect to the viewer, the recording's absolute address built from
the address the browser used: so the page does not depend on the ports (a page rendered for one
``--serve`` is right for the next), and a page of the static site has the plain link only.
"""

from __future__ import annotations

import socket
from urllib.parse import quote

from ..errors import SafeEmbodAIError

#: The site server's path that redirects to the viewer: ``/rerun-viewer/runs/<run>/recordings/<trial>.rrd``.
VIEWER_PREFIX = "/rerun-viewer/"
INSTALL = 'pip install -e ".[rerun]"'


class ViewerUnavailable(SafeEmbodAIError):
    """Rerun's web viewer cannot be served here (no ``rerun-sdk``); the site is served without it."""


def start_web_viewer(port: int = 0, tries: int = 5) -> int:
    """Serve Rerun's web viewer on ``port`` (0: any free one) and return the port it listens on.

    Raises :class:`ViewerUnavailable` without ``rerun-sdk`` and :class:`SafeEmbodAIError` when the
    port cannot be had (``port`` 0: after ``tries`` free ports were taken before the viewer got them)."""
    try:
        import rerun
    except ImportError:
        raise ViewerUnavailable(f"rerun-sdk is not installed ({INSTALL})") from None
    for _ in range(tries if port == 0 else 1):
        chosen = port or _free_port()
        try:
            rerun.serve_web_viewer(web_port=chosen, open_browser=False)
            return chosen
        except RuntimeError as error:  # rerun: "Failed to create server: Address already in use ..."
            if port or "in use" not in str(error):
                raise SafeEmbodAIError(f"Rerun's web viewer cannot listen on port {chosen}: {error}; choose "
                                       "another with --viewer-port (0: any free one)") from None
    raise SafeEmbodAIError(f"Rerun's web viewer found no free port in {tries} tries; choose one with --viewer-port")


def _free_port() -> int:
    """A port free on every interface now (the viewer listens on ``0.0.0.0``); taken again before
    the viewer binds it, :func:`start_web_viewer` tries another."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as probe:
        probe.bind(("0.0.0.0", 0))
        return int(probe.getsockname()[1])


def viewer_host(hostname: str) -> str:
    """The host name the viewer is reached by, given the one the site was: the same (it listens on
    every IPv4 interface), IPv6 loopback as IPv4's."""
    return "127.0.0.1" if hostname in ("[::1]", "::1") else hostname


def viewer_url(hostname: str, port: int, recording_url: str) -> str:
    """The viewer on ``hostname:port`` opening ``recording_url`` (percent-encoded whole: its ``url``
    query parameter)."""
    return f"http://{viewer_host(hostname)}:{port}/?url={quote(recording_url, safe='')}"
