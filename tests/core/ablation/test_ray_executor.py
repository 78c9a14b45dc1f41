"""Trials on a local Ray instance give the same results, steps and pictures as one process, all
written by the coordinator (needs the ray extra)."""

from __future__ import annotations

import pytest

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.scenario import load_scenario

ray = pytest.importorskip("ray", reason='the ray extra is not installed: pip install -e ".[ray]"')

pytestmark = [pytest.mark.ray, pytest.mark.slow]


@pytest.fixture(scope="module")
def local_ray():
    ray.init(address="local", num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             _node_ip_address="127.0.0.1")
    yield
    ray.shutdown()


def _timeless(value):
    """``value`` without the wall-clock latencies of the LLM calls (the only thing that differs)."""
    if isinstance(value, dict):
        return {k: _timeless(v) for k, v in value.items() if k != "latency_s"}
    if isinstance(value, list):
        return [_timeless(v) for v in value]
    return value


def _run(scenario, plugins, folder, **kwargs):
    ablation = Ablation(scenario, plugins, RunFolder(folder), **kwargs)
    try:
        results = {r.spec.trial_id: r for r in ablation.run()}
        steps = {trial_id: _timeless([s.model_dump(mode="json") for s in ablation.store.steps(trial_id)])
                 for trial_id in results}
    finally:
        ablation.close()
    pictures = {p.name: p.read_bytes() for p in (folder / "trajectories").glob("*.png")}
    return results, steps, pictures


def test_ray_executor_matches_serial(repo, plugins, tmp_path, local_ray):
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=2", "max_steps=4"], plugins.registry)
    runs = {name: _run(scenario, plugins, tmp_path / name, **kwargs) for name, kwargs in (
        ("serial", {}), ("ray", {"executor": "ray", "workers": 2}),
        ("ray_threads", {"executor": "ray", "workers": 2, "concurrency": 3}))}
    serial_results, serial_steps, serial_pictures = runs["serial"]
    assert len(serial_results) == 8 and len(serial_pictures) == 8
    for name in ("ray", "ray_threads"):  # three trials in flight in each actor's threads, too
        results, steps, pictures = runs[name]
        assert {k: r.model_dump(exclude={"wall_time_s", "node"}) for k, r in results.items()} == {
            k: r.model_dump(exclude={"wall_time_s", "node"}) for k, r in serial_results.items()}
        assert steps == serial_steps  # every step, written by the coordinator as it arrived
        assert pictures == serial_pictures
        [node] = [n for n in ray.nodes() if n["Alive"]]
        assert {r.node for r in results.values()} == {f"{node['NodeManagerAddress']}/{node['NodeID'][:8]}"}
        assert all(r.node is None for r in serial_results.values())
