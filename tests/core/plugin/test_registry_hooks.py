"""A third-party plugin can supply every kind of component, and a scenario selects them by name."""

from __future__ import annotations

import types

import yaml
from pydantic import BaseModel, ConfigDict

from safeembodai_core import hookimpl
from safeembodai_core.contracts.components import BackendReply, LLMBackend, Perception, PromptBuilder
from safeembodai_core.models import Modalities, Outcome, Prompt, TextPart
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.runs.runner import ScenarioRunner, trial_spec
from safeembodai_core.scenario import parse_scenario
from safeembodai_core.testing import CorridorWorld, answer, straight


class WallOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")
    wall_mm: float = 1500.0


class Empty(BaseModel):
    model_config = ConfigDict(extra="forbid")


class CountingPerception(Perception):
    def perceive(self, observation):
        return Modalities(texts={"lidar_text": f"front {observation.lidar.ranges_mm[0]:.0f} mm"})


class PlainPrompt(PromptBuilder):
    def build(self, request):
        return Prompt(system="drive", user=(TextPart("user", request.modalities.texts["lidar_text"]),))


class Cautious(LLMBackend):
    """Reads the text modality and always moves a third of the way to the wall."""

    def complete(self, prompt, rng):
        front = float(prompt.user_text.split()[1])
        return BackendReply(text=answer(straight(min(390, front / 3))))


class ListStore:
    """A minimal third-party store: ``record_step`` replaces the step's earlier record (the
    write-ahead contract: a step is recorded before its plan runs, then again with its results)."""

    def __init__(self):
        self.records, self.results, self.writes = [], [], []

    def begin_trial(self, spec):
        self.records.clear()
        self.writes.clear()

    def record_step(self, record):
        self.writes.append(record.status)
        self.records = [r for r in self.records if r.step != record.step] + [record]

    def reference_state(self, trial_id, step):
        return None

    def end_trial(self, result):
        self.results.append(result)

    def steps(self, trial_id):
        return list(self.records)

    def close(self):
        pass


STORE = ListStore()


def make_plugin():
    plugin = types.ModuleType("everything_plugin")
    plugin.register_environments = hookimpl(
        lambda register: register("corridor", lambda o, c: CorridorWorld(wall_mm=o.wall_mm), options=WallOptions))
    plugin.register_perceptions = hookimpl(
        lambda register: register("counting", lambda o, c: CountingPerception(), options=Empty))
    plugin.register_prompt_builders = hookimpl(
        lambda register: register("plain", lambda o, c: PlainPrompt(), options=Empty))
    plugin.register_state_stores = hookimpl(lambda register: register("list", lambda o, c: STORE, options=Empty))
    plugin.register_llm_backends = hookimpl(
        lambda register: register("cautious", lambda o, c: Cautious(), options=Empty))
    return plugin


def test_every_component_kind_can_come_from_a_third_party_plugin():
    plugins = load_plugins([make_plugin()], environ={})
    scenario = parse_scenario(yaml.safe_dump({
        "name": "custom", "max_steps": 10,
        "environments": [{"use": "corridor", "options": {"wall_mm": 1500}}],
        "perception": "counting", "prompt_builder": "plain", "state": "list", "backend": "cautious",
        "arms": {"guarded": {"safety_validation": True}}, "conditions": {"calm": {}},
    }), "custom.yaml", registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    result = runner.run(trial_spec(scenario, "corridor", "guarded", "calm", 0))
    assert result.outcome == Outcome.COMPLETED
    assert STORE.results[-1] == result and len(STORE.records) == result.steps
    assert STORE.writes == ["executing", "done"] * result.steps  # every plan on record before it ran
    first = STORE.records[0].executed[0].signal
    assert first.distance == 390  # a third of 1500 mm capped by the plan: from our perception and backend


def test_each_registry_hook_attributes_components_to_the_plugin():
    registry = load_plugins([make_plugin()], environ={}).registry
    owners = {(info.kind, info.name): info.plugin for info in registry.all()}
    for key in [("environment", "corridor"), ("perception", "counting"), ("prompt_builder", "plain"),
                ("state_store", "list"), ("llm_backend", "cautious")]:
        assert owners[key] == "everything_plugin"
