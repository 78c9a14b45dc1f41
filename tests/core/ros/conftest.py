"""A small MO run recorded with bags, shared by the bag tests (one ablation per session)."""

from __future__ import annotations

from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]


@pytest.fixture(scope="session")
def bag_run(tmp_path_factory):
    """``scenarios/mo.yaml``, one trial per cell, a careless mock pilot (so the guard refuses plans),
    run with ``ablate --bags mcap``: (scenario, run folder, results, store steps by trial id)."""
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugins import load_plugins
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins(environ={})
    scenario = load_scenario(REPO / "scenarios" / "mo.yaml", [
        "trials=1", "seed=5", "max_steps=8",
        "backend={use: mock, options: {ignore_clearance_p: 0.9, malformed_p: 0.2}}"],
        plugins.registry)
    path = tmp_path_factory.mktemp("bag-run") / "run"
    ablation = Ablation(scenario, plugins, RunFolder(path), bags="mcap")
    try:
        results = ablation.run()
        steps = {r.spec.trial_id: ablation.store.steps(r.spec.trial_id) for r in results}
    finally:
        ablation.close()
    return scenario, path, results, steps


@pytest.fixture(scope="session")
def moving_bag_run(tmp_path_factory):
    """``scenarios/dynamic.yaml``'s ``told`` arm, named ``moving`` here (the moving-obstacle rule, which
    reads the earlier scans) in DO, three trials, run with ``ablate --bags mcap``: as :func:`bag_run`.
    Not the shipped ``moving`` arm: its ``fresh_scan`` judges a reading the bag does not hold (the bag's
    scans are the steps'), so ``guard-bag`` cannot judge its plans as the trial did."""
    import yaml

    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugins import load_plugins
    from safeembodai_core.scenario import load_scenario

    data = yaml.safe_load((REPO / "scenarios" / "dynamic.yaml").read_text(encoding="utf-8"))
    data.update(arms={"moving": data["arms"]["told"]}, environments=data["environments"][:1], trials=3,
                max_steps=12, conditions={"no_attack": {}})
    folder = tmp_path_factory.mktemp("moving-bag-run")
    (folder / "moving.yaml").write_text(yaml.safe_dump(data), encoding="utf-8")
    plugins = load_plugins(environ={})
    scenario = load_scenario(folder / "moving.yaml", [], plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(folder / "run"), bags="mcap")
    try:
        results = ablation.run()
        steps = {r.spec.trial_id: ablation.store.steps(r.spec.trial_id) for r in results}
    finally:
        ablation.close()
    return scenario, folder / "run", results, steps
