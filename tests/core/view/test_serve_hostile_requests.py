"""``view --serve`` meets hostile requests and a hostile served tree: what it serves is the file it
opened -- a regular file reached from the site folder with no symlink anywhere -- and a request it
cannot read is answered with its status line (400, 404, 414, 505), never a traceback, a hang or an
endless body. Raw sockets, each with a timeout: no test here can hang."""

from __future__ import annotations

import os
import socket
import threading
from pathlib import Path

import pytest

from safeembodai_core.view.serve import SiteServer

SECRET = b"TOP-SECRET"


@pytest.fixture
def site(tmp_path) -> Path:
    """A site folder with its index, a page inside, and a folder outside it holding a secret."""
    folder = tmp_path / "site"
    (folder / "runs").mkdir(parents=True)
    (folder / "index.html").write_text("<html>index</html>")
    (folder / "runs" / "page.html").write_text("<html>page</html>")
    outside = tmp_path / "outside"
    outside.mkdir()
    (outside / "passwd").write_bytes(SECRET)
    return folder


def served(folder: Path) -> SiteServer:
    return SiteServer(folder, lambda: None, port=0, interval_s=3600).start()


def exchange(server: SiteServer, request: bytes, timeout: float = 10.0) -> bytes:
    """What the server answers ``request`` (sent as it is, from a thread: a long one may be cut off);
    at most 256 kB of it. socket.timeout when no answer ends within ``timeout``."""
    port = server.httpd.server_address[1]
    with socket.create_connection(("127.0.0.1", port), timeout=timeout) as conn:
        def send() -> None:
            try:
                conn.sendall(request)
            except OSError:  # the server answered and closed before reading it all (414)
                pass

        sender = threading.Thread(target=send, daemon=True)
        sender.start()
        answer = b""
        while len(answer) < 256 * 1024:
            chunk = conn.recv(65536)
            if not chunk:
                break
            answer += chunk
        sender.join(timeout)
        return answer


def get(server: SiteServer, target: str | bytes, version: bytes = b"HTTP/1.1") -> bytes:
    port = server.httpd.server_address[1]
    line = target if isinstance(target, bytes) else target.encode("latin-1")
    return exchange(server, b"GET " + line + b" " + version + b"\r\nHost: 127.0.0.1:%d\r\n\r\n" % port)


def status(answer: bytes) -> int:
    first = answer.split(b"\r\n", 1)[0].split()
    assert first[:1] == [b"HTTP/1.0"], answer[:200]  # a status line, always
    return int(first[1])


def test_a_symlink_named_like_a_scheme_serves_nothing_outside(site, tmp_path):
    (site / "http:").mkdir()
    (site / "http:" / "cfg").symlink_to(tmp_path / "outside")  # http:/cfg/passwd is the secret
    (site / "inside.html").symlink_to(site / "index.html")  # a symlink, even to a page of the site
    server = served(site)
    try:
        for target in ("http://cfg/passwd", "http://127.0.0.1/index.html", "*"):  # a path only
            answer = get(server, target)
            assert status(answer) == 400 and SECRET not in answer, target
        answer = get(server, "//cfg/passwd")  # 400 here; http.server >= 3.11.4 makes it /cfg/passwd first
        assert status(answer) in (400, 404) and SECRET not in answer
        for target in ("/http:/cfg/passwd", "/http%3A/cfg/passwd", "/inside.html"):
            answer = get(server, target)
            assert status(answer) == 404 and SECRET not in answer, target
        assert status(get(server, "/runs/page.html")) == 200
        assert b"<html>page</html>" in get(server, "/runs/page.html?x=1#y")
    finally:
        server.stop()


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_is_refused_at_once(site):
    os.mkfifo(site / "pipe.html")
    os.mkfifo(site / "runs" / "pipe.rrd")
    server = served(site)
    try:
        assert status(get(server, "/pipe.html")) == 404  # answered, not held
        assert status(get(server, "/runs/pipe.rrd")) == 404
        assert status(get(server, "/index.html")) == 200  # and the server still serves
    finally:
        server.stop()


@pytest.mark.skipif(not Path("/dev/zero").exists(), reason="no /dev/zero here")
def test_a_device_is_refused_not_streamed():
    devices = served(Path("/dev"))  # a site whose files are devices, reached with no symlink
    try:
        for device in ("/zero", "/null", "/urandom"):
            answer = get(devices, device)
            assert status(answer) == 404 and len(answer) < 4096, device  # no endless body
    finally:
        devices.stop()


@pytest.mark.parametrize("target", ["/index.html%00", "/%00", "/runs%00/page.html", "/index.html%0d%0aX: y",
                                    "/index.html%ff", "/index.html%1b"])
def test_a_target_with_a_null_byte_or_a_control_character_is_a_bad_request(site, capsys, target):
    server = served(site)
    try:
        assert status(get(server, target)) == 400
    finally:
        server.stop()
    assert "Traceback" not in capsys.readouterr().err


@pytest.mark.parametrize("request_line, expected", [
    (b"GET /" + b"a" * 70_000 + b" HTTP/1.1", 414),
    (b"GET /" + b"a" * 1_000_000 + b" HTTP/1.1", 414),
    (b"FOO/1.1", 400),
    (b"GET / HTTP/9.9", 505),
    (b"GET / HTTP/1.1 four", 400),
    (b"GET /index.html FOO/1.1", 400),
    (b"GET /index.html HTTP/0.9", 505),  # http.server would send the page alone: no status line, no CSP header
    (b"GET / HTTP/0.9\r\n" + b"X: y\r\n" * 120, 505),  # and its 431 for too many headers, bare
], ids=["70kB", "1MB", "one-word", "HTTP/9.9", "four-words", "bad-version", "HTTP/0.9", "HTTP/0.9-431"])
def test_a_malformed_request_line_gets_its_status(site, capsys, request_line, expected):
    server = served(site)
    port = server.httpd.server_address[1]
    try:
        answer = exchange(server, request_line + b"\r\nHost: 127.0.0.1:%d\r\n\r\n" % port)
        assert status(answer) == expected
        assert status(get(server, "/index.html")) == 200
    finally:
        server.stop()
    assert "Traceback" not in capsys.readouterr().err


def test_a_silent_connection_is_closed_after_the_request_timeout(site, monkeypatch):
    from safeembodai_core.view import serve

    monkeypatch.setattr(serve._Handler, "timeout", 0.5)
    server = served(site)
    try:
        port = server.httpd.server_address[1]
        with socket.create_connection(("127.0.0.1", port), timeout=10) as silent:
            silent.sendall(b"GET /index.html HTTP/1.1\r\n")  # and never the end of the headers
            assert silent.recv(1024) == b""  # closed by the server, not by this test's timeout
    finally:
        server.stop()


def test_connections_beyond_the_cap_are_closed_and_the_server_serves_on(site, monkeypatch):
    from safeembodai_core.view import serve

    monkeypatch.setattr(serve, "MAX_CONNECTIONS", 4)
    server = served(site)
    port = server.httpd.server_address[1]
    held = [socket.create_connection(("127.0.0.1", port), timeout=10) for _ in range(4)]
    try:
        for sock in held:
            sock.sendall(b"GET /index.html HTTP/1.1\r\n")  # held open, each by a thread of the server
        with socket.create_connection(("127.0.0.1", port), timeout=10) as extra:
            extra.sendall(b"GET /index.html HTTP/1.0\r\nHost: 127.0.0.1:%d\r\n\r\n" % port)
            assert extra.recv(1024) == b""  # no thread for it: closed unanswered
    finally:
        for sock in held:
            sock.close()
    for _ in range(50):  # the held threads see their clients gone and give their slots back
        answer = exchange(server, b"GET /index.html HTTP/1.0\r\nHost: 127.0.0.1:%d\r\n\r\n" % port)
        if answer.startswith(b"HTTP/1.0 200"):
            break
    server.stop()
    assert answer.startswith(b"HTTP/1.0 200"), answer[:80]
