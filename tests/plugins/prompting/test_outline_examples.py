"""The outline's example values: the ways ``schema_outline`` can show a distance and an
angle, the seeded outline's determinism in the prompt builder, and the bench that compares them."""

from __future__ import annotations

import importlib.util
import json
import sys
from pathlib import Path

import numpy as np
import pytest

from safeembodai_core.models import ControlLimits, ResponseParseError, parse_response
from safeembodai_core.models.response import OUTLINE_EXAMPLES, schema_outline
from safeembodai_plugins.prompting import JinjaPromptOptions
from safeembodai_plugins.prompting.builder import OUTLINE_EXAMPLES as BUILDER_DEFAULT
from safeembodai_plugins.prompting.builder import JinjaPromptBuilder, outline_rng

TIGHT = ControlLimits(max_distance_mm=150, max_angle_deg=1, max_signals=4)
BENCH = Path(__file__).resolve().parents[3] / "bench" / "real_model.py"


def _shown(outline: str) -> list[tuple[str, float]]:
    return [(e["command"], e.get("distance", e.get("angle"))) for e in json.loads(outline)["control"]]


def _copied(outline: str) -> str:
    data = json.loads(outline)
    data["control"] = [{**e, "direction": e["direction"].split("|")[0]} for e in data["control"]]
    return json.dumps(data)


@pytest.mark.parametrize("limits", [ControlLimits(), TIGHT])
@pytest.mark.parametrize("examples", ["half", "varied", "seeded"])
def test_a_copied_outline_is_a_valid_answer(examples, limits):
    for seed in range(20):
        outline = schema_outline(limits, examples, np.random.default_rng(seed))
        assert parse_response(_copied(outline), limits)


def test_each_way_of_showing_the_values():
    assert _shown(schema_outline()) == [("straight", 200), ("turn", 45)]
    assert _shown(schema_outline(examples="varied")) == [("turn", 19), ("straight", 120), ("turn", 70),
                                                         ("straight", 320)]
    assert _shown(schema_outline(examples="zero")) == [("straight", 0), ("turn", 0)]
    with pytest.raises(ResponseParseError, match="greater than 0"):
        parse_response(_copied(schema_outline(examples="zero")))
    drawn = {tuple(_shown(schema_outline(examples="seeded", rng=np.random.default_rng(s)))) for s in range(30)}
    assert len(drawn) == 30
    with pytest.raises(ValueError, match="needs an rng"):
        schema_outline(examples="seeded")
    with pytest.raises(ValueError, match="examples must be one of"):
        schema_outline(examples="random")


def _request(scene: int, step: int = 1):
    from safeembodai_core.models import Modalities, PromptRequest

    texts = {"camera_text": f"Camera: scene {scene}.", "lidar_text": "LiDAR nearest obstacle: front 1.00 m."}
    return PromptRequest(instruction="Find the red can.", modalities=Modalities(texts=texts), step=step)


def test_the_seeded_outline_is_the_same_for_the_same_step_and_differs_between_scenes():
    first, again = (JinjaPromptBuilder(JinjaPromptOptions(), outline_examples="seeded") for _ in range(2))
    assert first.build(_request(1)).system == again.build(_request(1)).system
    outlines = {schema_outline(examples="seeded", rng=outline_rng(_request(scene, step)))
                for scene in range(10) for step in (1, 2)}
    assert len(outlines) == 20
    assert schema_outline(examples="seeded", rng=outline_rng(_request(3))) in first.build(_request(3)).system


def test_the_builder_shows_the_chosen_variant_by_default(plugins):
    assert BUILDER_DEFAULT in OUTLINE_EXAMPLES
    system = plugins.registry.build("prompt_builder", "jinja", {}).build(_request(1)).system
    expected = schema_outline(examples=BUILDER_DEFAULT, rng=outline_rng(_request(1)))
    assert f"no other text: {expected}\n" in system


def _bench():
    spec = importlib.util.spec_from_file_location("real_model_bench_outline", BENCH)
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def test_the_bench_scenes_put_the_can_in_view_in_every_other_scene():
    bench = _bench()
    assert bench.OUTLINE_EXAMPLES == OUTLINE_EXAMPLES
    scenes = bench.outline_scenes(8, 0)
    assert all(scene.bearing_deg is None for scene in scenes[0::2])
    sides = [scene.bearing_deg > 0 for scene in scenes[1::2] if scene.bearing_deg is not None]
    assert len(sides) >= 3 and True in sides and False in sides
    assert [s.request for s in bench.outline_scenes(8, 0)] == [s.request for s in scenes]  # reproducible


def test_the_bench_table_has_one_row_per_variant():
    row = {"valid": 23, "answers": 24, "signals": 40, "copied_examples": 10, "old_examples_200_45": 12,
           "distances": "150 (100-200), 9 distinct", "angles": "30 (20-45), 7 distinct", "first_turn_toward_can": 5,
           "answers_in_view_with_a_turn": 8, "can_in_view_off_centre": 12, "turns_left": 15, "turn_signals": 20,
           "forward_inside_front_clearance": 9, "first_signal_forward": 10}
    table = _bench().outline_table({"half": row, "seeded": row}).splitlines()
    assert len(table) == 4 and table[2].startswith("| `half` | 23/24 | 10/40 | 12/40 |")
