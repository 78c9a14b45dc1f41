"""Start the documented local model server (llama-cpp-python's OpenAI-compatible server) and stop it.

For the ``local`` backend's users, its real-server test and ``bench/real_model.py``: one place that
starts ``python -m llama_cpp.server`` on a free loopback port, waits until ``/v1/models`` answers,
and stops the process by its PID on exit (SIGTERM, then SIGKILL after ``stop_timeout_s``)::

    with llama_cpp_server("/path/model.gguf", log_path=Path("server.log")) as url:
        ...  # {"use": "local", "options": {"api_base": url}}

Needs the ``local-model`` extra (``bash .ci/install_local_model.sh``); nothing here downloads.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from safeembodai_core.errors import BackendError


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on right now."""
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        return probe.getsockname()[1]


@contextmanager
def llama_cpp_server(model_path: str | Path, *, log_path: Path, threads: int = 2, n_ctx: int = 4096,
                     chat_format: str | None = None, start_timeout_s: float = 180.0,
                     stop_timeout_s: float = 20.0) -> Iterator[str]:
    """The OpenAI-compatible base URL (``http://127.0.0.1:<port>/v1``) of a server on ``model_path``.

    The server's output goes to ``log_path``; a server that exits or does not answer within
    ``start_timeout_s`` raises :class:`BackendError` with the end of that log. Without
    ``chat_format`` the GGUF's own chat template is used.
    """
    port = free_port()
    command = [sys.executable, "-m", "llama_cpp.server", "--model", str(model_path), "--host", "127.0.0.1",
               "--port", str(port), "--n_ctx", str(n_ctx), "--n_threads", str(threads)]
    if chat_format:
        command += ["--chat_format", chat_format]
    with log_path.open("w") as sink:
        server = subprocess.Popen(command, stdout=sink, stderr=subprocess.STDOUT)
    url = f"http://127.0.0.1:{port}/v1"
    try:
        deadline = time.monotonic() + start_timeout_s
        while not _answers(url):
            if server.poll() is not None or time.monotonic() > deadline:
                tail = log_path.read_text(errors="replace")[-3000:]
                raise BackendError(f"llama-cpp-python server on {model_path} did not start (log {log_path}):\n{tail}")
            time.sleep(0.5)
        yield url
    finally:
        if server.poll() is None:
            os.kill(server.pid, signal.SIGTERM)
            try:
                server.wait(timeout=stop_timeout_s)
            except subprocess.TimeoutExpired:
                os.kill(server.pid, signal.SIGKILL)
                server.wait()


def _answers(url: str) -> bool:
    try:
        with urllib.request.urlopen(f"{url}/models", timeout=2) as answer:
            return answer.status == 200
    except OSError:
        return False
