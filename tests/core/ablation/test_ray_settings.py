"""How the ray executor connects and places its workers, checked without Ray installed (a stand-in module)."""

from __future__ import annotations

import os
import signal
import socket
import sys
import time
from types import SimpleNamespace

import pytest

from safeembodai_core.ablation.ray_executor import MAX_RESTARTS, RayConnectError, RayExecutor, connect, host_and_port


def fake_ray(seen: dict, init=None) -> SimpleNamespace:
    def default_init(**kwargs):
        seen["usage_stats"] = os.environ.get("RAY_USAGE_STATS_ENABLED")
        seen["kwargs"] = kwargs
        signal.signal(signal.SIGTERM, lambda *a: sys.exit(15))  # what Ray's init does in a driver

    def options(**kwargs):
        seen["actor_options"] = kwargs
        return SimpleNamespace(remote=lambda *args: object())

    return SimpleNamespace(is_initialized=lambda: False, init=init or default_init, exceptions=SimpleNamespace(),
                           remote=lambda cls: SimpleNamespace(options=options))


def test_a_run_never_phones_home_unless_the_user_says_so(monkeypatch):
    seen: dict = {}
    monkeypatch.setitem(sys.modules, "ray", fake_ray(seen))
    monkeypatch.delenv("RAY_USAGE_STATS_ENABLED", raising=False)
    RayExecutor({}, None, workers=1, address=None)
    assert seen["usage_stats"] == "0"
    assert seen["kwargs"]["include_dashboard"] is False and seen["kwargs"]["_node_ip_address"] == "127.0.0.1"
    monkeypatch.setenv("RAY_USAGE_STATS_ENABLED", "1")  # turned on by the user: left on
    RayExecutor({}, None, workers=1, address=None)
    assert seen["usage_stats"] == "1"


def test_workers_run_threads_and_are_replaced_by_the_executor_not_restarted_by_ray(monkeypatch):
    seen: dict = {}
    monkeypatch.setitem(sys.modules, "ray", fake_ray(seen))
    RayExecutor({}, None, workers=2, address=None, concurrency=16)
    assert seen["actor_options"] == {"max_concurrency": 16, "max_restarts": 0, "max_task_retries": 0,
                                     "num_cpus": 0, "scheduling_strategy": "SPREAD"}  # no node listed: Ray's SPREAD
    assert MAX_RESTARTS >= 1


def test_no_address_is_a_ray_of_this_machine_whatever_RAY_ADDRESS_says(monkeypatch):
    seen: dict = {}
    monkeypatch.setenv("RAY_ADDRESS", "10.0.0.1:6379")
    ray = fake_ray(seen)
    assert connect(ray, None) == "a Ray of this machine"
    assert seen["kwargs"]["address"] == "local"  # Ray starts its own and ignores RAY_ADDRESS


def test_rays_sigterm_handler_is_replaced_by_the_runs_own(monkeypatch):
    ours = lambda *a: None  # noqa: E731
    previous = signal.signal(signal.SIGTERM, ours)
    try:
        connect(fake_ray({}), None)
        assert signal.getsignal(signal.SIGTERM) is ours
    finally:
        signal.signal(signal.SIGTERM, previous)


@pytest.mark.parametrize("address", ["nonsense", "host:", ":6379", "host:99999", "ray://", "http://h/x:1"])
def test_a_malformed_address_is_refused_naming_it(address):
    with pytest.raises(RayConnectError, match="is not HOST:PORT"):
        host_and_port(address)


def test_addresses_are_split():
    assert host_and_port("10.0.0.1:6379") == ("10.0.0.1", 6379)
    assert host_and_port("ray://head:10001") == ("head", 10001)
    assert host_and_port("[::1]:6379") == ("::1", 6379)


def test_an_address_where_nothing_listens_fails_at_once_naming_it():
    with socket.socket() as s:  # a port of this machine that nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    start = time.monotonic()
    with pytest.raises(RayConnectError, match=f"127.0.0.1:{port}"):
        connect(fake_ray({}), f"127.0.0.1:{port}", timeout_s=5)
    assert time.monotonic() - start < 5


def test_a_listening_port_that_never_answers_as_ray_fails_within_the_timeout():
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        address = f"127.0.0.1:{server.getsockname()[1]}"
        hung = fake_ray({}, init=lambda **kwargs: time.sleep(30))  # Ray's init retrying forever
        with pytest.raises(RayConnectError, match=f"{address}: no connection within 0.5 s"):
            connect(hung, address, timeout_s=0.5)
        with pytest.raises(RayConnectError, match=r"try again\.$"):  # Ray Client's own flakiness is named
            connect(hung, f"ray://{address}", timeout_s=0.5)


def test_a_connection_ray_refuses_is_one_line_naming_the_address():
    with socket.socket() as server:
        server.bind(("127.0.0.1", 0))
        server.listen()
        address = f"127.0.0.1:{server.getsockname()[1]}"

        def refused(**kwargs):
            raise ConnectionError("Traceback...\nFailed to connect to Ray cluster")

        with pytest.raises(RayConnectError, match=f"{address}: ConnectionError: Failed to connect to Ray cluster$"):
            connect(fake_ray({}, init=refused), address, timeout_s=5)
