"""Trials on a Ray cluster (the ``ray`` extra): workers anywhere, the run folder on the coordinator.

One Ray actor per worker, each running up to ``concurrency`` trials at once (a threaded actor),
spread over the cluster's nodes (Ray's ``SPREAD`` strategy). No worker writes the run folder: each
trial streams what it leaves to the coordinator, which writes it as it arrives (``relay.py``), so no
shared disk is needed and ``--out`` may be relative.

A lost node (its raylet killed, the machine gone) costs only the trials it was running: each runs
again from its start on a remaining worker (a lost worker is replaced by a new one on a node that
lost none, up to :data:`MAX_RESTARTS` times per worker; the response cache hands the re-run the
replies already paid for). A trial cut off :data:`MAX_TRIAL_TRIES` times, or a cluster left with no
worker, stops the run with :class:`~.executors.WorkersLost`: finished trials are recorded, and a
resume finishes the rest.

Connecting: no address is a Ray of this machine only (``RAY_ADDRESS`` is ignored then); ``auto``
lets Ray find one (``RAY_ADDRESS`` or a cluster started here); ``HOST:PORT`` and ``ray://HOST:PORT``
(Ray Client) name one. A named address is checked for a listening port first and the connection is
given ``connect_timeout_s``: a wrong address fails in seconds with a message naming it, never hangs.
"""

from __future__ import annotations

import logging
import os
import signal
import socket
import threading
from collections import Counter, deque
from typing import Any, Iterator

from ..errors import SafeEmbodAIError
from ..logs import get_logger
from ..models import TrialResult, TrialSpec
from ..runs.trial_files import ArtefactSettings
from .executors import POLL_S, WorkersLost
from .relay import RelayedWrites, RelayError, RelayWorker

log = get_logger(__name__)

#: How many times a worker is replaced after its process or its node was lost.
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
    quiet = _NotMainThreadNote()
    logging.getLogger("ray").addFilter(quiet)
    logging.getLogger("ray._private.worker").addFilter(quiet)
    try:
        thread.start()
        thread.join(timeout_s)
    finally:
        logging.getLogger("ray").removeFilter(quiet)
        logging.getLogger("ray._private.worker").removeFilter(quiet)
    if thread.is_alive():
        client = (" Ray Client's server on the head fails now and then to start a server for a new client "
                  "(ray-project/ray#63202): try again." if address.startswith("ray://") else "")
        raise RayConnectError(f"cannot connect to the Ray cluster at {address}: no connection within {timeout_s:g} s "
                              f"(--connect-timeout; is it a Ray head, and is this its Ray version?).{client}")
    if failure:
        first = (str(failure[0]).strip().splitlines() or [""])[-1][:300]
        raise RayConnectError(f"cannot connect to the Ray cluster at {address}: "
                              f"{type(failure[0]).__name__}: {first}") from None


class _NotMainThreadNote(logging.Filter):
    """Drops Ray's note that it set no SIGTERM handler when connecting from a thread: the run keeps
    its own on purpose (see :func:`connect`)."""

    def filter(self, record: logging.LogRecord) -> bool:
        return "SIGTERM handler is not set" not in record.getMessage()


def _lost_errors(ray: Any) -> tuple[type[BaseException], ...]:
    """What Ray raises for a trial whose worker, its node or its results were lost (a worker killed for
    memory included)."""
    e = ray.exceptions
    return tuple(getattr(e, name) for name in ("RayActorError", "WorkerCrashedError", "NodeDiedError",
                                               "ObjectLostError", "ActorUnschedulableError", "OutOfMemoryError")
                 if hasattr(e, name))


def _last_line(error: BaseException) -> str:
    """The last line of Ray's message (it carries the remote traceback before it)."""
    lines = [line.strip() for line in str(error).splitlines() if line.strip()]
    return (lines[-1] if lines else type(error).__name__)[:300]


def _live_nodes(ray: Any) -> list[str]:
    """The cluster's live nodes (their ids, by address); empty where they cannot be listed."""
    try:
        return [node_id for _, node_id in sorted((node["NodeManagerAddress"], node["NodeID"])
                                                 for node in ray.nodes() if node.get("Alive"))]
    except (AttributeError, KeyError, TypeError):
        return []


def _client_mode(ray: Any) -> bool:
    """Whether this process reaches its cluster through Ray Client (``ray://``)."""
    try:
        return bool(ray.util.client.ray.is_connected())
    except AttributeError:  # a Ray without the client (or a stand-in)
        return False


class _Slot:
    """One worker: its actor, the node it was put on, its trials in flight, and how often it was replaced."""

    def __init__(self, actor: Any, node: str | None) -> None:
        self.actor, self.node = actor, node
        self.load = self.replaced = 0
        self.generation = 0  # bumped with each new actor: a loss reported by an older one is not a new loss
        self.alive = True


class RayExecutor:
    """``workers`` Ray actors (:class:`~.relay.RelayWorker`), fed one trial at a time each thread;
    what they send is written by ``writes`` (the coordinator's :class:`~.relay.RelayedWrites`).

    Placement: the cluster's live nodes in turn, each actor pinned to its node (Ray's ``SPREAD``, and a
    soft affinity, both put every worker of a two-node cluster on one node at times: the workers ask for
    no CPU, as a trial's CPU use is the worker's own business). A worker that is lost (its process or
    its node) is replaced by a new actor on a node that has lost none, up to :data:`MAX_RESTARTS` times."""

    def __init__(self, scenario_json: dict[str, Any], writes: RelayedWrites, workers: int, address: str | None,
                 concurrency: int = 1, *, artefacts: ArtefactSettings = ArtefactSettings(), cache: bool = False,
                 connect_timeout_s: float = CONNECT_TIMEOUT_S) -> None:
        ray = self.ray = _ray()
        self.writes, self.concurrency = writes, concurrency
        self._owns_connection = not ray.is_initialized()
        if self._owns_connection:  # the CLI connects before making the run folder; a library caller may not have
            connect(ray, address, connect_timeout_s)
        self._arguments = (scenario_json, concurrency, workers, artefacts, cache)
        self._class = ray.remote(RelayWorker)
        self._lost = _lost_errors(ray)
        self._failed: tuple[type[BaseException], ...] = tuple(
            error for error in (getattr(getattr(ray, "exceptions", None), "RayTaskError", None),) if error)
        self._suspect: set[str] = set()  # nodes that lost a worker
        nodes = _live_nodes(ray)
        self.slots = [_Slot(*self._start(nodes[k % len(nodes)] if nodes else None)) for k in range(workers)]
        #: Ray Client streams nothing back: a trial's events then come all at once, when it is over
        self.streaming = not _client_mode(ray)

    @property
    def actors(self) -> list[Any]:
        return [slot.actor for slot in self.slots]

    def _start(self, node: str | None) -> tuple[Any, str | None]:
        """A new actor on ``node`` (pinned), or where Ray's ``SPREAD`` puts it when no node is named."""
        placement: Any = "SPREAD"
        if node is not None:
            from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

            placement = NodeAffinitySchedulingStrategy(node_id=node, soft=False)
        actor = self._class.options(max_concurrency=self.concurrency, max_restarts=0, max_task_retries=0, num_cpus=0,
                                    scheduling_strategy=placement).remote(*self._arguments)
        return actor, node

    def _replace(self, slot: _Slot) -> None:
        """Put a lost worker's slot on a node that has lost none (any live node if every one has)."""
        if slot.node is not None:
            self._suspect.add(slot.node)
        try:
            self.ray.kill(slot.actor)
        except Exception:  # noqa: BLE001 -- an actor of a lost node: nothing to stop
            pass
        if slot.replaced >= MAX_RESTARTS:
            slot.alive = False
            return
        nodes = _live_nodes(self.ray)
        healthy = [node for node in nodes if node not in self._suspect] or nodes
        used = Counter(other.node for other in self.slots if other.alive and other is not slot)
        node = min(healthy, key=lambda n: used[n]) if healthy else None
        slot.actor, slot.node = self._start(node)
        slot.load = 0  # the old actor's trials in flight are lost with it (and re-queued as they report it)
        slot.replaced += 1
        slot.generation += 1
        log.warning("ray.worker_replaced", node=node, times=slot.replaced)

    def run(self, specs: list[TrialSpec]) -> Iterator[TrialResult]:
        """Trials' results as they finish; each trial's records written before its result is yielded."""
        ray = self.ray
        waiting = deque(specs)
        tries: Counter[str] = Counter()
        running: dict[Any, tuple[_Slot, int, TrialSpec]] = {}
        started: set[Any] = set()  # streams whose trial began on its worker
        while waiting or running:
            for slot in self.slots:
                while waiting and slot.alive and slot.load < self.concurrency:
                    spec = waiting.popleft()
                    method = slot.actor.run if self.streaming else slot.actor.run_whole
                    stream = method.remote(spec.model_dump(mode="json"), self.writes.replies_for(spec))
                    running[stream] = (slot, slot.generation, spec)
                    slot.load += 1
            if not running:
                raise WorkersLost(f"the Ray cluster has no worker left ({len(waiting)} trials not run)")
            ready, _ = ray.wait(list(running), num_returns=1, timeout=POLL_S)
            for stream in ready:
                slot, generation, spec = running[stream]
                try:
                    events = [ray.get(next(stream))] if self.streaming else ray.get(stream)
                except StopIteration:
                    events = None
                except self._lost as error:
                    if getattr(error, "actor_init_failed", False):  # a node without the project, say
                        raise WorkersLost(f"a Ray worker could not start on its node: {_last_line(error)}") from None
                    events = error
                except self._failed as error:  # an error of the worker's own, not of Ray's
                    raise RelayError(f"a Ray worker failed on trial {spec.trial_id}: {_last_line(error)}") from None
                if events is None or isinstance(events, BaseException):
                    del running[stream]
                    if generation == slot.generation:
                        self._replace(slot)  # its other trials in flight fail too, and are re-queued
                    self._cut_off(spec, events, stream in started or not self.streaming, tries, waiting)
                    started.discard(stream)
                    continue
                started.add(stream)
                for event in events if isinstance(events, list) else ():
                    result = self.writes.receive(spec, event)
                    if result is not None:
                        del running[stream]
                        started.discard(stream)
                        if generation == slot.generation:
                            slot.load -= 1
                        yield result
                        break
                else:
                    if not self.streaming:  # a whole trial must end with its result
                        raise RelayError(f"a Ray worker sent trial {spec.trial_id} without its end")

    def _cut_off(self, spec: TrialSpec, error: BaseException | None, began: bool, tries: Counter[str],
                 waiting: deque) -> None:
        """A trial whose worker was lost: queued to run again from its start, or the run stops. A trial
        that had not begun (its worker was already gone) is not counted against it."""
        why = type(error).__name__ if error is not None else "its stream ended early"
        if began:
            tries[spec.trial_id] += 1
        log.warning("ray.trial_cut_off", trial=spec.trial_id, began=began, tries=tries[spec.trial_id], error=why)
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
        self.slots = []
        if self._owns_connection:
            self.ray.shutdown()
            self._owns_connection = False

    abort = close

