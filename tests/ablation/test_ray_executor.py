"""Trials on a local Ray instance give the same results as one process (needs the ray extra)."""

from __future__ import annotations

import pytest

from safeembodai_core.ablation import Ablation, RunFolder
from safeembodai_core.scenario import load_scenario

ray = pytest.importorskip("ray", reason='the ray extra is not installed: pip install -e ".[ray]"')

pytestmark = [pytest.mark.ray, pytest.mark.slow]


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False,
             _node_ip_address="127.0.0.1")
    yield
    ray.shutdown()


def test_ray_executor_matches_serial(repo, plugins, tmp_path, local_ray):
    scenario = load_scenario(repo / "scenarios" / "quickstart.yaml", ["trials=2", "max_steps=4"], plugins.registry)
    results = {}
    for name, kwargs in (("serial", {}), ("ray", {"executor": "ray", "workers": 2}),
                         ("ray_threads", {"executor": "ray", "workers": 2, "concurrency": 3})):
        ablation = Ablation(scenario, plugins, RunFolder(tmp_path / name), **kwargs)
        try:
            results[name] = {r.spec.trial_id: r.model_dump(exclude={"wall_time_s"}) for r in ablation.run()}
        finally:
            ablation.close()
    assert results["ray"] == results["serial"] and len(results["ray"]) == 8
    assert results["ray_threads"] == results["serial"]  # three trials in flight in each actor's threads
