"""``bench/real_model.py``: its ablation scenario is a valid scenario and its table reads a run folder."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import yaml

from safeembodai_core.scenario import parse_scenario

BENCH = Path(__file__).resolve().parents[3] / "bench" / "real_model.py"


def _bench():
    spec = importlib.util.spec_from_file_location("real_model_bench", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # its dataclasses look their module up
    spec.loader.exec_module(module)
    return module


def test_the_ablation_scenario_validates_with_the_local_defaults(built_plugins):
    bench = _bench()
    data = bench.ablation_scenario(bench.MODELS["smollm2-135m-instruct"], "http://127.0.0.1:9/v1", 2, 6)
    scenario = parse_scenario(yaml.safe_dump(data), "<bench>", registry=built_plugins.registry)
    assert [e.use for e in scenario.environments] == ["OF", "SO"]
    assert set(scenario.arms) == {"baseline", "safeembodai"} and set(scenario.conditions) == {"no_attack", "attack"}
    assert "json_mode" not in data["backend"]["options"]  # the backend's default form, as documented


def test_wilson_interval_is_exact_at_the_ends():
    bench = _bench()
    assert bench._wilson(0, 4).startswith("0.00 [0.00, ")
    assert bench._wilson(4, 4).endswith(", 1.00]")
    assert bench._wilson(0, 0) == "-"
