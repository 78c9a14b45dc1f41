"""The litellm backends' preflight: is the server there, before the first trial?

The key was checked when the backend was built (a missing key is a build error). Here one TCP
connection is opened to the host the calls would go to -- ``api_base`` when set, else the
provider's default endpoint as litellm knows it (OpenAI's honours ``OPENAI_BASE_URL`` /
``OPENAI_API_BASE``), or the proxy an ``HTTPS_PROXY``/``HTTP_PROXY`` variable routes it through --
and closed at once: no request is sent, no token is spent. A provider whose endpoint litellm does
not name (Anthropic, Azure without ``api_base``, ...) is not probed; its first call tells.
"""

from __future__ import annotations

import os
import socket
import urllib.request
from typing import Any
from urllib.parse import urlsplit

from safeembodai_core.errors import BackendError

PREFLIGHT_TIMEOUT_S = 5.0
_OPENAI_DEFAULT = "https://api.openai.com/v1"


def endpoint(options: Any, litellm: Any) -> str | None:
    """The URL the backend's calls go to, or None when it cannot be told without calling."""
    if options.api_base:
        return options.api_base
    try:
        _, provider, _, base = litellm.get_llm_provider(options.model)
    except Exception:  # an id litellm cannot place: the first call will say why
        return None
    if base:
        return base
    if provider == "openai":
        return os.environ.get("OPENAI_BASE_URL") or os.environ.get("OPENAI_API_BASE") or _OPENAI_DEFAULT
    return None


def _host_port(url: str) -> tuple[str, str, int]:
    """(scheme, host, port) of ``url``; user and password, if any, are never shown."""
    parts = urlsplit(url if "://" in url else f"http://{url}")
    try:
        port = parts.port
    except ValueError:  # a port that is no number
        port = None
    return parts.scheme, parts.hostname or "", port or (443 if parts.scheme == "https" else 80)


def _address(url: str) -> tuple[str, int, str]:
    """(host, port, what) to connect to for ``url``: the proxy's when one applies."""
    scheme, host, port = _host_port(url)
    proxy = urllib.request.getproxies().get(scheme)
    if proxy and host and not urllib.request.proxy_bypass(host):
        _, via_host, via_port = _host_port(proxy)
        return via_host, via_port, f"the proxy {via_host}:{via_port} for {host}:{port}"
    return host, port, f"{host}:{port}"


def check_reachable(name: str, options: Any, litellm: Any) -> None:
    """Raise :class:`BackendError` (one line) when the backend's server does not accept a connection."""
    url = endpoint(options, litellm)
    if url is None:
        return
    host, port, what = _address(url)
    if not host:
        raise BackendError(f"llm backend {name!r}: api_base names no host")
    timeout = min(PREFLIGHT_TIMEOUT_S, options.timeout_s)
    try:
        socket.create_connection((host, port), timeout=timeout).close()
    except socket.gaierror:
        reason = f"the name {host!r} does not resolve"
    except TimeoutError:
        reason = f"no answer within {timeout:g} s"
    except OSError as error:
        reason = error.strerror or type(error).__name__
    else:
        return
    raise BackendError(f"llm backend {name!r} (model {options.model}) cannot reach {what} ({reason}); "
                       "start the server, or fix api_base or the network")
