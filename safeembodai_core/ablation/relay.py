"""Trials on other machines, the run folder on this one: workers send, the coordinator writes.

A Ray worker may run on a node with its own disk and its own working directory, so it never
writes the run folder. Everything a trial leaves -- its steps as they are recorded (the one before
a motion included), the result, the replies of a paid model, its picture, its bag and its recording -- travels to
the coordinator as a stream of events (a Ray streaming generator per trial), and the coordinator
writes each as it arrives, in the order the trial made it: the same order as a worker writing
directly. Not the same moment: nothing waits for the coordinator's write, so a worker may be a few
steps ahead of the run folder, and a failed write there stops the run after the worker went on (a
serial run would have stopped the trial before its motion ran). A trial cut off meanwhile runs again
from its start.

The worker side keeps the records of its trials in flight (R_{i-1} for the next prompt and the
bag's steps come from them) and forgets a trial once its stream ends. The coordinator side reads
each event as untrusted input: a record, result or reply that does not validate, or one that
belongs to another trial, stops the run with an error naming the trial; a file name that is not
one the trial may write is refused.

Events (a tuple each): ``("node", name)``, ``("begin", spec)``, ``("step", record)``,
``("reply", key, stored text)``, ``("end", result)`` (the result stored), ``("picture", png)``,
``("bag", {file name: bytes})``, ``("recording", rrd)``, ``("done", result)`` (the trial is over),
``("failed", message)``.
"""

from __future__ import annotations

import os
import queue
import re
import threading
from typing import Any, Iterable, Iterator

from ..contracts.components import StateStore
from ..errors import SafeEmbodAIError
from ..models import ReferenceState, StepRecord, TrialResult, TrialSpec
from ..models.reply import BackendReply
from ..runs.files import MAX_RECORDING_BYTES, RRD_MAGIC
from ..trust.text import storable
from ..runs.trial_files import MAX_BAG_FILES, ArtefactSettings, FolderFiles, TrialFiles, TrialOutputs, bag_bytes

#: The largest picture and bag file a worker may send (bytes).
MAX_FILE_BYTES = 256 * 1024 * 1024
_BAG_FILE_NAME = re.compile(r"[A-Za-z0-9_.-]{1,200}")
_NODE_NAME = re.compile(r"[\x21-\x7e]{1,80}")


class RelayError(SafeEmbodAIError):
    """A worker sent something the coordinator does not write (names the trial)."""


# -- the worker's side ---------------------------------------------------------------------------


class RelayHub:
    """A worker's outboxes, one per trial in flight, and the records and kept replies of those trials."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._outboxes: dict[str, queue.SimpleQueue[tuple[Any, ...]]] = {}
        self.records: dict[str, dict[int, StepRecord]] = {}
        self.replies: dict[str, str] = {}
        self._keys: dict[str, list[str]] = {}

    def open(self, trial_id: str, replies: dict[str, str]) -> queue.SimpleQueue[tuple[Any, ...]]:
        outbox: queue.SimpleQueue[tuple[Any, ...]] = queue.SimpleQueue()
        with self._lock:
            self._outboxes[trial_id] = outbox
            self.records[trial_id] = {}
            self.replies.update(replies)
            self._keys[trial_id] = list(replies)
        return outbox

    def close(self, trial_id: str) -> None:
        with self._lock:
            self._outboxes.pop(trial_id, None)
            self.records.pop(trial_id, None)
            for key in self._keys.pop(trial_id, []):
                self.replies.pop(key, None)

    def send(self, trial_id: str, event: tuple[Any, ...]) -> None:
        with self._lock:
            outbox = self._outboxes.get(trial_id)
        if outbox is None:
            raise SafeEmbodAIError(f"trial {trial_id!r} is not running in this worker")
        outbox.put(event)


class RelayStore(StateStore):
    """The state store of a worker that writes no run folder: each write goes to the coordinator;
    R_{i-1} and the steps of a trial in flight are answered from the records sent (cleaned for
    storage as every store cleans them, so the next prompt is what it would be on the coordinator)."""

    def __init__(self, hub: RelayHub) -> None:
        self.hub = hub

    def begin_trial(self, spec: TrialSpec) -> None:
        self.hub.records[spec.trial_id] = {}
        self.hub.send(spec.trial_id, ("begin", spec.model_dump(mode="json")))

    def record_step(self, record: StepRecord) -> None:
        kept = storable(record)
        self.hub.records.setdefault(record.trial_id, {})[record.step] = kept
        self.hub.send(record.trial_id, ("step", kept.model_dump(mode="json")))

    def reference_state(self, trial_id: str, step: int) -> ReferenceState | None:
        previous = self.hub.records.get(trial_id, {}).get(step - 1)
        return previous.to_reference() if previous is not None else None

    def end_trial(self, result: TrialResult) -> None:
        self.hub.send(result.spec.trial_id, ("end", storable(result).model_dump(mode="json")))

    def steps(self, trial_id: str) -> list[StepRecord]:
        records = self.hub.records.get(trial_id, {})
        return [records[step].model_copy(deep=True) for step in sorted(records)]

    @property
    def thread_safe(self) -> bool:
        return True  # each trial's records are its own thread's


class RelayFiles(TrialFiles):
    """A trial's picture and bag, sent to the coordinator."""

    def __init__(self, hub: RelayHub) -> None:
        self.hub = hub

    def picture(self, trial_id: str, png: bytes) -> None:
        self.hub.send(trial_id, ("picture", bytes(png)))

    def bag(self, trial_id: str, messages: Iterable[tuple[str, int, Any]], storage: str) -> None:
        self.hub.send(trial_id, ("bag", bag_bytes(trial_id, messages, storage)))

    def recording(self, trial_id: str, rrd: bytes) -> None:
        self.hub.send(trial_id, ("recording", bytes(rrd)))


class RelayCache:
    """The response cache of a worker: the trial's kept replies, handed over with the trial, are read
    back; each new reply goes to the coordinator, which keeps it (so a trial re-run after its node was
    lost replays what was paid for)."""

    def __init__(self, hub: RelayHub) -> None:
        self.hub = hub

    def get(self, key: str) -> BackendReply | None:
        from ..loop.response_cache import stored_reply

        text = self.hub.replies.get(key)
        return stored_reply(text) if text is not None else None

    def put(self, key: str, reply: BackendReply, trial_id: str | None = None) -> None:
        from ..loop.response_cache import stored_text

        if trial_id is None:
            return
        try:
            self.hub.send(trial_id, ("reply", key, stored_text(reply)))
        except ValueError:  # a number JSON cannot hold: not kept, as the run folder's cache would not
            pass


def relay_outputs(hub: RelayHub, artefacts: ArtefactSettings, cache: bool) -> TrialOutputs:
    """What a relaying worker's runners write through."""
    return TrialOutputs(files=RelayFiles(hub), settings=artefacts, cache=RelayCache(hub) if cache else None)


def relay_trial(hub: RelayHub, pool: Any, node: str, spec_json: dict[str, Any],
                replies: dict[str, str]) -> Iterator[tuple[Any, ...]]:
    """Run one trial in a thread of ``pool`` and yield its events as they happen, ``("done",
    result)`` or ``("failed", message)`` last."""
    spec = TrialSpec.model_validate(spec_json)
    outbox = hub.open(spec.trial_id, replies)

    def work() -> None:
        try:
            done = ("done", pool.run(spec).model_dump(mode="json"))
        except BaseException as error:  # the runner records component failures itself: this is a bug
            done = ("failed", f"{type(error).__name__}: {error}")
        outbox.put(done)

    try:
        yield ("node", node)
        threading.Thread(target=work, name=f"trial-{spec.trial_id}", daemon=True).start()
        while True:
            event = outbox.get()
            yield event
            if event[0] in ("done", "failed"):
                return
    finally:
        hub.close(spec.trial_id)


class RelayWorker:
    """A Ray actor's body (``ray.remote(RelayWorker)``): runs trials with ``concurrency`` threads and
    streams what they leave (:func:`relay_trial`); writes nothing on its node but scratch bags."""

    def __init__(self, scenario_json: dict[str, Any], concurrency: int, workers: int, artefacts: ArtefactSettings,
                 cache: bool) -> None:
        from .runner_pool import RATE_SHARE, RunnerPool, worker_logging

        os.environ[RATE_SHARE] = str(workers)
        worker_logging()
        self.hub = RelayHub()
        self.pool = RunnerPool(scenario_json, None, concurrency, state=RelayStore(self.hub),
                               outputs=relay_outputs(self.hub, artefacts, cache))
        self.node = node_name()

    def run(self, spec_json: dict[str, Any], replies: dict[str, str]) -> Iterator[tuple[Any, ...]]:
        """The trial's events as they happen (a Ray streaming generator)."""
        yield from relay_trial(self.hub, self.pool, self.node, spec_json, replies)

    def run_whole(self, spec_json: dict[str, Any], replies: dict[str, str]) -> list[tuple[Any, ...]]:
        """The trial's events all at once, when it is over: for Ray Client, which streams nothing."""
        return list(relay_trial(self.hub, self.pool, self.node, spec_json, replies))


def node_name() -> str:
    """This Ray node as a person can tell it: the address it has in the cluster and the start of its id."""
    import ray

    node_id = ray.get_runtime_context().get_node_id()
    address = next((node.get("NodeManagerAddress") for node in ray.nodes() if node.get("NodeID") == node_id), None)
    return f"{address or ray.util.get_node_ip_address()}/{node_id[:8]}"


# -- the coordinator's side ----------------------------------------------------------------------


class RelayedWrites:
    """The coordinator's end: writes what workers send into the run folder as it arrives."""

    def __init__(self, store: StateStore, run_dir: str, cache: Any = None) -> None:
        self.store, self.files, self.cache = store, FolderFiles(run_dir), cache
        self._nodes: dict[str, str] = {}
        self._ended: set[str] = set()  # trials whose result the store holds, awaiting their "done"

    def replies_for(self, spec: TrialSpec) -> dict[str, str]:
        """The kept replies a worker is handed with ``spec`` (none without a cache)."""
        return self.cache.replies_of(spec.trial_id) if self.cache is not None else {}

    def receive(self, spec: TrialSpec, event: Any) -> TrialResult | None:
        """Write one event of ``spec``'s trial; the trial's result once it is over, else None."""
        trial = spec.trial_id
        if not (isinstance(event, tuple) and event and isinstance(event[0], str)):
            raise RelayError(f"a worker sent a malformed event for trial {trial}")
        kind, payload = event[0], event[1:]
        if kind == "node" and len(payload) == 1 and isinstance(payload[0], str) and _NODE_NAME.fullmatch(payload[0]):
            self._nodes[trial] = payload[0]
        elif kind == "begin" and len(payload) == 1:
            if _model(TrialSpec, payload[0], trial) != spec:
                raise RelayError(f"a worker began another trial than {trial}")
            self._ended.discard(trial)
            self.store.begin_trial(spec)
        elif kind == "step" and len(payload) == 1:
            record = _model(StepRecord, payload[0], trial)
            if record.trial_id != trial:
                raise RelayError(f"a worker sent a step of {record.trial_id!r} as one of trial {trial}")
            self.store.record_step(record)
        elif kind == "reply" and len(payload) == 2:
            self._keep_reply(trial, *payload)
        elif kind in ("end", "done") and len(payload) == 1:
            result = self._result(spec, payload[0])
            if kind == "end":
                self.store.end_trial(result)
                self._ended.add(trial)
                return None
            if trial not in self._ended:  # a result the store never got would be counted as finished
                raise RelayError(f"a worker ended trial {trial} without storing its result first")
            self._ended.discard(trial)
            self._nodes.pop(trial, None)
            return result
        elif kind == "picture" and len(payload) == 1 and isinstance(payload[0], bytes):
            self.files.picture(trial, _bounded(payload[0], trial, "picture"))
        elif kind == "bag" and len(payload) == 1:
            self.files.bag_folder(trial, _bag_files(payload[0], trial))
        elif kind == "recording" and len(payload) == 1 and isinstance(payload[0], bytes):
            self.files.recording(trial, _recording(payload[0], trial))
        elif kind == "failed" and len(payload) == 1:
            raise RelayError(f"a worker failed on trial {trial}: {str(payload[0])[:500]}")
        else:
            raise RelayError(f"a worker sent an event the coordinator does not write for trial {trial}: "
                             f"{kind[:40]!r}")
        return None

    def node(self, trial_id: str) -> str | None:
        return self._nodes.get(trial_id)

    def _result(self, spec: TrialSpec, payload: Any) -> TrialResult:
        result = _model(TrialResult, payload, spec.trial_id)
        if result.spec != spec:
            raise RelayError(f"a worker sent the result of {result.spec.trial_id!r} as that of trial {spec.trial_id}")
        return result.model_copy(update={"node": self._nodes.get(spec.trial_id)})

    def _keep_reply(self, trial: str, key: Any, text: Any) -> None:
        from ..loop.response_cache import stored_reply

        if self.cache is None:
            return
        if not (isinstance(key, str) and isinstance(text, str) and stored_reply(text) is not None):
            raise RelayError(f"a worker sent a reply for trial {trial} that is not one")
        try:
            self.cache.put_text(key, text, trial)
        except ValueError as error:
            raise RelayError(f"a worker sent a reply for trial {trial} under a bad key: {error}") from None


def _model(model: Any, payload: Any, trial: str) -> Any:
    from pydantic import ValidationError

    try:
        return model.model_validate(payload)
    except ValidationError as error:
        first = error.errors()[0]
        where = ".".join(str(part) for part in first["loc"]) or "(root)"
        raise RelayError(f"a worker sent a {model.__name__} for trial {trial} that does not validate: "
                         f"{where}: {first['msg']}") from None


def _bounded(data: bytes, trial: str, what: str) -> bytes:
    if len(data) > MAX_FILE_BYTES:
        raise RelayError(f"a worker sent a {what} of {len(data)} bytes for trial {trial} (at most {MAX_FILE_BYTES})")
    return data


def _recording(data: bytes, trial: str) -> bytes:
    if len(data) > MAX_RECORDING_BYTES or not data.startswith(RRD_MAGIC):
        raise RelayError(f"a worker sent a recording for trial {trial} that is not a Rerun recording of at most "
                         f"{MAX_RECORDING_BYTES} bytes")
    return data


def _bag_files(files: Any, trial: str) -> dict[str, bytes]:
    if not (isinstance(files, dict) and 0 < len(files) <= MAX_BAG_FILES):
        raise RelayError(f"a worker sent a bag for trial {trial} that is not a few named files")
    for name, data in files.items():
        if not (isinstance(name, str) and _BAG_FILE_NAME.fullmatch(name) and name not in (".", "..")
                and isinstance(data, bytes)):
            raise RelayError(f"a worker sent a bag file for trial {trial} with a name it may not write: "
                             f"{str(name)[:80]!r}")
        _bounded(data, trial, "bag file")
    return files
