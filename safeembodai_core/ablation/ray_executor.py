"""Trials on a Ray cluster (the ``ray`` extra): workers anywhere, the run folder on the coordinator.

One Ray actor per worker, each running up to ``concurrency`` trials at once (a threaded actor),
spread over the cluster's nodes (Ray's ``SPREAD`` strategy). No worker writes the run folder: each
trial streams what it leaves to the coordinator, which writes it as it arrives (``relay.py``), so no
shared disk is needed and ``--out`` may be relative.

A lost node (its raylet killed, the machine gone) costs only the trials it was running: each runs
again from its start on a remaining worker (an actor whose node is lost starts again elsewhere, up to
:data:`MAX_RESTARTS` times; the response cache hands the re-run the replies already paid for). A
trial cut off :data:`MAX_TRIAL_TRIES` times, or a cluster left with no worker, stops the run with
:class:`~.executors.WorkersLost`: finished trials are recorded, and a resume finishes the rest.

Connecting: no address is a Ray of this machine only (``RAY_ADDRESS`` is ignored then); ``auto``
lets Ray find one (``RAY_ADDRESS`` or a cluster started here); ``HOST:PORT`` and ``ray://HOST:PORT``
(Ray Client) name one. A named address is checked for a listening port first and the connection is
given ``connect_timeout_s``: a wrong address fails in seconds with a message naming it, never hangs.
"""

from __future__ import annotations

import os
import signal
import socket
import threading
from collections import Counter, deque
from typing import Any, Iterator

from ..errors import SafeEmbodAIError
from ..logs import get_logger
from ..models import TrialResult, TrialSpec
from .executors import POLL_S, WorkersLost
from .relay import RelayedWrites, RelayWorker

log = get_logger(__name__)

#: How many times an actor is started again after its worker process or node was lost.
MAX_RESTARTS = 3
#: How many times a trial may be cut off by a lost worker before the run stops.
MAX_TRIAL_TRIES = 3
#: The default for ``--connect-timeout``.
CONNECT_TIMEOUT_S = 30.0


class RayConnectError(SafeEmbodAIError):
    """The Ray cluster named by ``--address`` cannot be reached (names the address)."""


def _ray() -> Any:
    try:
        import ray
    except ImportError:
        raise SafeEmbodAIError('the ray executor needs the ray extra: pip install -e ".[ray]"') from None
    return ray


def host_and_port(address: str) -> tuple[str, int]:
    """``HOST:PORT`` or ``ray://HOST:PORT`` (``[v6]:PORT`` too) split; RayConnectError when it is neither."""
    rest = address.removeprefix("ray://")
    host, sep, port = rest.rpartition(":")
    host = host.strip("[]")
    if not (sep and host and port.isdigit() and 0 < int(port) < 65536 and "/" not in host):
        raise RayConnectError(f"--address {address!r} is not HOST:PORT, ray://HOST:PORT or auto")
    return host, int(port)


def probe(address: str, timeout_s: float) -> None:
    """Fail at once, naming ``address``, when nothing listens there."""
    host, port = host_and_port(address)
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            return
    except OSError as error:
        reason = "no answer" if isinstance(error, TimeoutError) else (error.strerror or str(error))
        raise RayConnectError(f"cannot reach the Ray cluster at {address}: {reason} "
                              f"(waited at most {timeout_s:g} s; check --address)") from None


def connect(ray: Any, address: str | None, timeout_s: float = CONNECT_TIMEOUT_S) -> str:
    """Connect this process to Ray (see the module docstring); return the address it is connected to.

    Ray's ``init`` installs its own SIGTERM handler in the driver: the run's own (a clean stop, exit
    143 and the resume line) is put back."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")  # a run must not phone home unless the user said so
    main = threading.current_thread() is threading.main_thread()
    previous = signal.getsignal(signal.SIGTERM) if main else None
    options = dict(include_dashboard=False, log_to_driver=False, ignore_reinit_error=True, configure_logging=False)
    try:
        if address is None:
            ray.init(address="local", _node_ip_address="127.0.0.1", **options)
            return "a Ray of this machine"
        if address != "auto":
            probe(address, timeout_s)
        _init_within(ray, address, timeout_s, options)
    finally:
        if main and previous is not None:
            signal.signal(signal.SIGTERM, previous)
    return address


def _init_within(ray: Any, address: str, timeout_s: float, options: dict[str, Any]) -> None:
    """``ray.init(address)`` given ``timeout_s``: in a thread, as Ray offers no time limit of its own."""
    failure: list[BaseException] = []

    def init() -> None:
        try:
            ray.init(address=address, **options)
        except BaseException as error:  # reported below, by the caller's thread
            failure.append(error)

    thread = threading.Thread(target=init, name="ray-connect", daemon=True)
    thread.start()
    thread.join(timeout_s)
    if thread.is_alive():
        raise RayConnectError(f"cannot connect to the Ray cluster at {address}: no connection within {timeout_s:g} s "
                              "(--connect-timeout; is it a Ray head, and is this its Ray version?)")
    if failure:
        first = (str(failure[0]).strip().splitlines() or [""])[-1][:300]
        raise RayConnectError(f"cannot connect to the Ray cluster at {address}: "
                              f"{type(failure[0]).__name__}: {first}") from None


def _lost_errors(ray: Any) -> tuple[type[BaseException], ...]:
    """What Ray raises for a trial whose worker, its node or its results were lost."""
    e = ray.exceptions
    return tuple(getattr(e, name) for name in ("RayActorError", "WorkerCrashedError", "NodeDiedError",
                                               "ObjectLostError", "ActorUnschedulableError") if hasattr(e, name))


class RayExecutor:
    """``workers`` Ray actors (:class:`~.relay.RelayWorker`), fed one trial at a time each thread;
    what they send is written by ``writes`` (the coordinator's :class:`~.relay.RelayedWrites`)."""

    def __init__(self, scenario_json: dict[str, Any], writes: RelayedWrites, workers: int, address: str | None,
                 concurrency: int = 1, *, bag_storage: str | None = None, cache: bool = False,
                 connect_timeout_s: float = CONNECT_TIMEOUT_S) -> None:
        ray = self.ray = _ray()
        self.writes, self.concurrency = writes, concurrency
        self._owns_connection = not ray.is_initialized()
        self.address = connect(ray, address, connect_timeout_s) if self._owns_connection else "a running Ray"
        actor = ray.remote(RelayWorker).options(
            max_concurrency=concurrency, max_restarts=MAX_RESTARTS, max_task_retries=0,
            num_cpus=0, scheduling_strategy="SPREAD")
        self.actors = [actor.remote(scenario_json, concurrency, workers, bag_storage, cache) for _ in range(workers)]
        self._lost = _lost_errors(ray)

    def run(self, specs: list[TrialSpec]) -> Iterator[TrialResult]:
        """Trials' results as they finish; each trial's records written before its result is yielded."""
        ray = self.ray
        waiting = deque(specs)
        tries: Counter[str] = Counter()
        running: dict[Any, tuple[int, TrialSpec]] = {}
        load = [0] * len(self.actors)
        alive = [True] * len(self.actors)
        while waiting or running:
            for index, actor in enumerate(self.actors):
                while waiting and alive[index] and load[index] < self.concurrency:
                    spec = waiting.popleft()
                    stream = actor.run.remote(spec.model_dump(mode="json"), self.writes.replies_for(spec))
                    running[stream] = (index, spec)
                    load[index] += 1
            if not running:
                raise WorkersLost(f"the Ray cluster has no worker left ({len(waiting)} trials not run)")
            ready, _ = ray.wait(list(running), num_returns=1, timeout=POLL_S)
            for stream in ready:
                index, spec = running[stream]
                try:
                    event = ray.get(next(stream))
                except StopIteration:
                    event = None
                except self._lost as error:
                    event = error
                if event is None or isinstance(event, BaseException):
                    del running[stream]
                    load[index] -= 1
                    if isinstance(event, ray.exceptions.ActorDiedError):
                        alive[index] = False
                    self._cut_off(spec, event, tries, waiting)
                    continue
                result = self.writes.receive(spec, event)
                if result is not None:
                    del running[stream]
                    load[index] -= 1
                    yield result

    def _cut_off(self, spec: TrialSpec, error: BaseException | None, tries: Counter[str], waiting: deque) -> None:
        """A trial whose worker was lost: queued to run again from its start, or the run stops."""
        tries[spec.trial_id] += 1
        why = type(error).__name__ if error is not None else "its stream ended early"
        log.warning("ray.trial_cut_off", trial=spec.trial_id, tries=tries[spec.trial_id], error=why)
        if tries[spec.trial_id] >= MAX_TRIAL_TRIES:
            raise WorkersLost(f"trial {spec.trial_id} was cut off {tries[spec.trial_id]} times by a lost Ray worker "
                              f"(last: {why})")
        waiting.appendleft(spec)

    def close(self) -> None:
        for actor in self.actors:
            try:
                self.ray.kill(actor)
            except Exception:  # noqa: BLE001 -- an actor of a lost node or a lost cluster: nothing to stop
                pass
        self.actors = []
        if self._owns_connection:
            self.ray.shutdown()
            self._owns_connection = False

    abort = close

