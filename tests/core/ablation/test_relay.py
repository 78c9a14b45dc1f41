"""The relay without Ray: a worker's events carry a whole trial, and the coordinator writes exactly
what a worker writing the run folder itself would have, refusing events that are not its trial's."""

from __future__ import annotations

from pathlib import Path

import pytest

from safeembodai_core.ablation.relay import (RelayCache, RelayedWrites, RelayError, RelayHub, RelayStore,
                                             relay_outputs, relay_trial)
from safeembodai_core.ablation.runner_pool import RunnerPool
from safeembodai_core.loop.response_cache import ResponseCache, stored_text
from safeembodai_core.models import TokenUsage
from safeembodai_core.models.reply import BackendReply
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.runs.runner import ScenarioRunner
from safeembodai_core.scenario import load_scenario
from safeembodai_core.runs.trial_files import ArtefactSettings, recording_file


@pytest.fixture(scope="module")
def scenario(repo):
    plugins = load_plugins()
    return load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=1", "max_steps=3"], plugins.registry)


def _relayed(scenario, spec, replies=None, bags=None, recordings=False):
    """Every event one trial sends from a relaying worker."""
    hub = RelayHub()
    pool = RunnerPool(scenario.model_dump(mode="json"), None, 1, state=RelayStore(hub),
                      outputs=relay_outputs(hub, ArtefactSettings(bags, recordings), cache=True))
    try:
        return list(relay_trial(hub, pool, "127.0.0.9/abcdef01", spec.model_dump(mode="json"), replies or {}))
    finally:
        pool.close()


def _coordinator(scenario, folder: Path):
    runner = ScenarioRunner(scenario, load_plugins(), run_dir=folder)
    return runner, RelayedWrites(runner.state, str(folder), ResponseCache(folder / "responses"))


def test_the_coordinator_writes_what_a_worker_writing_directly_would(scenario, tmp_path):
    direct = ScenarioRunner(scenario, load_plugins(), run_dir=tmp_path / "direct", save_trajectories=True)
    spec = direct.specs()[-1]
    expected = direct.run(spec)
    expected_steps = [s.model_dump(exclude={"attempts"}) for s in direct.state.steps(spec.trial_id)]
    direct.close()

    events = _relayed(scenario, spec)
    kinds = [event[0] for event in events]
    assert kinds[0] == "node" and kinds[1] == "begin" and kinds[-1] == "done"
    assert kinds.index("end") < kinds.index("picture") < kinds.index("done")  # the result is stored first
    runner, writes = _coordinator(scenario, tmp_path / "relayed")
    try:
        results = [writes.receive(spec, event) for event in events]
        result = results[-1]
        assert result is not None and all(r is None for r in results[:-1])
        assert result.node == "127.0.0.9/abcdef01"
        timeless = {"wall_time_s", "node"}
        assert result.model_dump(exclude=timeless) == expected.model_dump(exclude=timeless)
        assert [s.model_dump(exclude={"attempts"}) for s in runner.state.steps(spec.trial_id)] == expected_steps
        [stored] = [r for r in runner.state.results() if r.spec.trial_id == spec.trial_id]
        assert stored.node == "127.0.0.9/abcdef01"
    finally:
        runner.close()
    name = spec.trial_id.replace("/", "__") + ".png"
    assert (tmp_path / "relayed" / "trajectories" / name).read_bytes() == \
        (tmp_path / "direct" / "trajectories" / name).read_bytes()


def test_each_step_is_sent_as_it_is_recorded_before_the_motion_runs(scenario):
    spec = ScenarioRunner(scenario, load_plugins()).specs()[0]
    steps = [event[1] for event in _relayed(scenario, spec) if event[0] == "step"]
    assert steps and steps[0]["status"] == "executing"  # the write-ahead record travels first
    assert [s["status"] for s in steps].count("done") >= 1


def test_a_bag_travels_as_its_files_and_lands_whole(scenario, tmp_path):
    spec = ScenarioRunner(scenario, load_plugins()).specs()[0]
    events = _relayed(scenario, spec, bags="mcap")
    [bag] = [event[1] for event in events if event[0] == "bag"]
    assert "metadata.yaml" in bag and any(name.endswith(".mcap") for name in bag)
    runner, writes = _coordinator(scenario, tmp_path)
    try:
        for event in events:
            writes.receive(spec, event)
    finally:
        runner.close()
    folder = tmp_path / "bags" / spec.trial_id.replace("/", "__")
    assert sorted(p.name for p in folder.iterdir()) == sorted(bag)


def test_a_recording_travels_and_lands_where_view_links_it(scenario, tmp_path):
    pytest.importorskip("rerun", reason="the rerun extra (pip install -e '.[rerun]') writes recordings")
    spec = ScenarioRunner(scenario, load_plugins()).specs()[0]
    events = _relayed(scenario, spec, recordings=True)
    [rrd] = [event[1] for event in events if event[0] == "recording"]
    kinds = [event[0] for event in events]
    assert rrd.startswith(b"RRF2") and kinds.index("end") < kinds.index("recording") < kinds.index("done")
    runner, writes = _coordinator(scenario, tmp_path)
    try:
        for event in events:
            writes.receive(spec, event)
        with pytest.raises(RelayError, match="not a Rerun recording"):
            writes.receive(spec, ("recording", b"<html>not one</html>"))
    finally:
        runner.close()
    assert recording_file(tmp_path, spec.trial_id).read_bytes() == rrd


def _reply(text="ok") -> BackendReply:
    return BackendReply(text=text, usage=TokenUsage(prompt_tokens=3, completion_tokens=2), latency_s=0.1, model="m")


def test_replies_go_to_the_coordinators_cache_and_come_back_with_a_rerun(tmp_path):
    cache = ResponseCache(tmp_path / "responses")
    hub = RelayHub()
    hub.open("E/a/c/0", {})
    key = "ab" * 32 + ":0"
    RelayCache(hub).put(key, _reply(), "E/a/c/0")
    writes = RelayedWrites(store=None, run_dir=str(tmp_path), cache=cache)  # a reply event needs no store
    event = ("reply", key, stored_text(_reply()))
    from safeembodai_core.models import TrialSpec

    spec = TrialSpec(trial_id="E/a/c/0", scenario="s", environment="E", arm="a", condition="c", index=0, seed=1)
    assert writes.receive(spec, event) is None
    assert cache.get(key) == _reply()
    handed = writes.replies_for(spec)  # what a worker is given when the trial runs again
    assert list(handed) == [key]
    worker = RelayHub()
    worker.open(spec.trial_id, handed)
    assert RelayCache(worker).get(key) == _reply()
    worker.close(spec.trial_id)
    assert RelayCache(worker).get(key) is None  # forgotten with the trial


@pytest.mark.parametrize("event, message", [
    ("nonsense", "malformed event"),
    (("teleport", 1), "does not write"),
    (("step", {"trial_id": "x"}), "does not validate"),
    (("bag", {"../../etc/passwd": b"x"}), "may not write"),
    (("bag", {"a": "text"}), "may not write"),
    (("bag", {}), "not a few named files"),
    (("picture", "not bytes"), "does not write"),
    (("reply", "ab" * 32 + ":0", "{not json"), "not one"),
    (("reply", "../x", stored_text(_reply())), "bad key"),
    (("failed", "RuntimeError: boom"), "failed on trial"),
])
def test_what_a_worker_may_not_send_is_refused_naming_the_trial(tmp_path, event, message):
    from safeembodai_core.models import TrialSpec

    spec = TrialSpec(trial_id="E/a/c/0", scenario="s", environment="E", arm="a", condition="c", index=0, seed=1)
    writes = RelayedWrites(store=None, run_dir=str(tmp_path), cache=ResponseCache(tmp_path / "responses"))
    with pytest.raises(RelayError, match=message) as error:
        writes.receive(spec, event)
    assert "E/a/c/0" in str(error.value)
    assert not (tmp_path / "bags").exists() or not any((tmp_path / "bags").iterdir())


def test_a_step_or_result_of_another_trial_is_refused(scenario, tmp_path):
    specs = ScenarioRunner(scenario, load_plugins()).specs()
    events = _relayed(scenario, specs[0])
    runner, writes = _coordinator(scenario, tmp_path)
    try:
        step = next(event for event in events if event[0] == "step")
        with pytest.raises(RelayError, match="as one of trial"):
            writes.receive(specs[1], step)
        done = events[-1]
        with pytest.raises(RelayError, match="as that of trial"):
            writes.receive(specs[1], done)
    finally:
        runner.close()


def test_a_fifo_at_a_trials_index_never_hangs_and_a_key_is_noted_once(tmp_path):
    import hashlib
    import os

    cache = ResponseCache(tmp_path / "responses")
    key = "cd" * 32 + ":0"
    cache.put(key, _reply(), "E/a/c/0")
    cache.put(key, _reply("again"), "E/a/c/0")  # --refresh called again: the index keeps one line
    assert list(cache.replies_of("E/a/c/0")) == [key]
    index = tmp_path / "responses" / "trials" / (hashlib.sha256(b"E/a/c/1").hexdigest() + ".keys")
    os.mkfifo(index)
    cache.put("ef" * 32 + ":0", _reply(), "E/a/c/1")  # returns: the reply is kept, its index line is not
    assert cache.get("ef" * 32 + ":0") == _reply()
    assert cache.replies_of("E/a/c/1") == {}
