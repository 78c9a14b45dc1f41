"""Run folders for the view's tests: a 40-trial MO run and a run whose answers are hostile."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]

#: What an LLM might write to attack a page that shows its words.
HOSTILE = ("<script>window.__pwned = 1</script><img src=x onerror=\"window.__pwned = 2\"> "
           "![tracker](http://evil.example/pixel.png) [click](javascript:alert(1)) "
           "\u202egnp.exe\u202c zero\u200bwidth NUL\x00 ESC\x1b[2J")


def run_into(path: Path, scenario_file: Path, overrides: list[str]) -> Path:
    from safeembodai_core.ablation import Ablation, RunFolder
    from safeembodai_core.plugin.manager import load_plugins
    from safeembodai_core.scenario import load_scenario

    plugins = load_plugins(environ={})
    scenario = load_scenario(scenario_file, overrides, plugins.registry)
    ablation = Ablation(scenario, plugins, RunFolder(path))
    try:
        results = ablation.run()
        from safeembodai_core.report import write_report

        write_report(path, scenario, results, store=ablation.store, plugins=plugins)
    finally:
        ablation.close()
    return path


@pytest.fixture(scope="session")
def runs_dir(tmp_path_factory) -> Path:
    """A folder of two runs: ``mo`` (scenarios/mo.yaml, 10 trials per cell = 40 trials) and
    ``hostile`` (quickstart's flatland, a scripted pilot whose answers carry :data:`HOSTILE`)."""
    root = tmp_path_factory.mktemp("view-runs")
    run_into(root / "mo-40", REPO / "scenarios" / "mo.yaml", ["trials=10", "max_steps=12"])
    good = {"perception": [{"input": "human_instruction", "result": HOSTILE, "is_attack": False}],
            "planning": HOSTILE, "control": [{"command": "turn", "direction": "left", "angle": 30}]}
    answers = [json.dumps(good), HOSTILE + json.dumps(good)]  # a good answer, then one that does not parse
    run_into(root / "hostile", REPO / "scenarios" / "quickstart.yaml", [
        "trials=1", "max_steps=3", f"instruction={json.dumps('Find the can. ' + HOSTILE)}",
        f"backend={json.dumps({'use': 'scripted', 'options': {'responses': answers}})}"])
    return root
