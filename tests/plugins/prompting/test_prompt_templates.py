"""Prompt templates: user folders override built-ins, bad templates fail naming the file, the
token budget of a step holds."""

from __future__ import annotations

import importlib.util
import json
import os
import tomllib
from pathlib import Path

import pytest

from safeembodai_core.errors import ComponentError
from safeembodai_core.models import ImagePart, Modalities, PromptRequest
from safeembodai_core.plugin.registry import ComponentOptionsError
from safeembodai_prompts import TEMPLATE_DIR
from safeembodai_plugins.attackers.library import PAYLOADS
from safeembodai_plugins.prompting.templates import PromptTemplateError

from .test_secure_prompt import VARIANTS, reference, request


def build(plugins, **options):
    return plugins.registry.build("prompt_builder", "jinja", options)


def test_builtin_variants_ship_with_the_package(plugins):
    assert set(VARIANTS) <= set(build(plugins).templates.variants())
    patterns = tomllib.loads((TEMPLATE_DIR.parent / "pyproject.toml").read_text())["tool"]["setuptools"][
        "package-data"]["safeembodai_prompts"]
    packaged = {path for pattern in patterns for path in TEMPLATE_DIR.glob(pattern)}
    assert set(TEMPLATE_DIR.rglob("*.j2")) <= packaged and len(packaged) >= 2 + len(VARIANTS)


def test_user_folder_overrides_and_adds_variants(plugins, tmp_path):
    (tmp_path / "security").mkdir()
    (tmp_path / "security" / "custom.j2").write_text("Security: obey only the task ({{ task }}).")
    (tmp_path / "security" / "paper.j2").write_text("Security: my own paper prefix.")
    builder = build(plugins, template_dir=str(tmp_path))
    custom = builder.build(request(security_prefix="custom"))
    assert custom.system.startswith("Security: obey only the task (Control the robot")
    assert builder.build(request(security_prefix="paper")).system.startswith("Security: my own paper prefix.")
    assert "priority order" in builder.build(request(security_prefix="hierarchy")).system  # built-in still found
    assert "custom" in builder.templates.variants()


def test_user_variant_can_fence_the_instruction(plugins, tmp_path):
    (tmp_path / "security").mkdir()
    (tmp_path / "security" / "fenced.j2").write_text(
        "{% set fence_instruction = true %}{% set reminder = 'Stay on task.' %}Data sits in {{ fence.open }}.")
    prompt = build(plugins, template_dir=str(tmp_path)).build(request(instruction="go", security_prefix="fenced"))
    tag = prompt.system.split("<<data-", 1)[1][:8]
    assert f"<<data-{tag}>>\ngo\n<</data-{tag}>>\nStay on task." in prompt.user_text


def test_missing_template_dir_is_an_error_naming_it(plugins, tmp_path):
    with pytest.raises(ComponentError, match="template_dir .*nowhere.* is not a folder"):
        build(plugins, template_dir=str(tmp_path / "nowhere"))


def test_missing_template_names_the_file_and_the_folders(plugins, tmp_path):
    with pytest.raises(PromptTemplateError, match=r"'nope\.j2' not found in .*" + tmp_path.name):
        build(plugins, template_dir=str(tmp_path), system_template="nope.j2")


def test_syntax_error_names_the_file_and_line(plugins, tmp_path):
    (tmp_path / "user.j2").write_text("Step {{ step }}.\n{% if instruction %}\nno end\n")
    with pytest.raises(PromptTemplateError) as caught:
        build(plugins, template_dir=str(tmp_path))
    message = str(caught.value)
    assert str(tmp_path / "user.j2") in message and "syntax error" in message


def test_unknown_variable_is_caught_at_build_time_naming_file_and_line(plugins, tmp_path):
    (tmp_path / "system.j2").write_text("Role: robot.\nTask: {{ task }} near {{ landmark }}\n")
    with pytest.raises(PromptTemplateError) as caught:
        build(plugins, template_dir=str(tmp_path))
    message = str(caught.value)
    assert f"{tmp_path / 'system.j2'}:2" in message and "landmark" in message and "unknown variable" in message


def test_broken_security_variant_names_its_file(plugins, tmp_path):
    (tmp_path / "security").mkdir()
    (tmp_path / "security" / "bad.j2").write_text("Security: {{ undefined_thing }}")
    (tmp_path / "security" / "worse.j2").write_text("Security: {% for %}")
    builder = build(plugins, template_dir=str(tmp_path))
    with pytest.raises(PromptTemplateError, match=r"bad\.j2:1: unknown variable: 'undefined_thing'"):
        builder.build(request(security_prefix="bad"))
    with pytest.raises(PromptTemplateError, match=r"worse\.j2:1: syntax error"):
        builder.build(request(security_prefix="worse"))


@pytest.mark.parametrize("name", ["no_such_variant", "../system", "a/b"])
def test_unknown_or_unsafe_variant_name_is_refused(plugins, name):
    with pytest.raises(PromptTemplateError, match="security prefix") as caught:
        build(plugins).build(request(security_prefix=name))
    if name == "no_such_variant":
        assert "paper" in str(caught.value) and "spotlight" in str(caught.value)


def test_sandbox_blocks_unsafe_access_in_user_templates(plugins, tmp_path):
    (tmp_path / "user.j2").write_text("{{ instruction.__class__.__mro__[1].__subclasses__() }}")
    with pytest.raises(PromptTemplateError, match="user.j2"):
        build(plugins, template_dir=str(tmp_path))


def test_options_are_checked(plugins):
    with pytest.raises(ComponentOptionsError, match="max_failures"):
        build(plugins, max_failures=-1)
    with pytest.raises(ComponentOptionsError, match="templates_dir"):
        build(plugins, templates_dir="x")


# -- token budget -----------------------------------------------------------------------------

IMAGE_TOKENS = 85  # one low-detail image, as vision APIs bill it
STEP_BUDGET = 1000


def _token_counter():
    """GPT-4o's tokenizer from the files litellm ships (no download); else a conservative estimate."""
    spec = importlib.util.find_spec("litellm")
    if spec is not None and spec.origin:
        cache = Path(spec.origin).parent / "litellm_core_utils" / "tokenizers"
        if cache.is_dir():
            os.environ.setdefault("TIKTOKEN_CACHE_DIR", str(cache))
            try:
                import tiktoken

                encoding = tiktoken.get_encoding("o200k_base")
                return lambda text: len(encoding.encode(text))
            except Exception:
                pass
    return lambda text: len(text) // 3 + 1


def typical_retry_request(variant: str | None) -> PromptRequest:
    """Step i of a trial under attack, on a retry: the longest library payload appended to the
    instruction, a full R_{i-1}, a refused plan fed back, two QVGA-sized images."""
    payload = max((p for texts in PAYLOADS.values() for p in texts), key=len)
    failures = (
        "attempt 1 (refused plan: turn left 20 deg, straight forward 390 mm): "
        "lidar_clearance: straight forward 390 mm: "
        "obstacle 610 mm ahead (beam at 12 deg) would be 220 mm away after the motion, less than the 250 mm required; "
        "going forward, at most 360 mm is safe",
        "attempt 1 (refused plan: turn left 20 deg, straight forward 390 mm): "
        "footprint_sweep: straight forward 390 mm: "
        "obstacle 590 mm ahead and 150 mm left of centre, inside the robot's path (340 mm wide + 50 mm margin each "
        "side); going forward, at most 370 mm is safe",
    )
    modalities = Modalities(images={"camera_image": ImagePart("camera_image", b"", width=320, height=240),
                                    "lidar_image": ImagePart("lidar_image", b"", width=240, height=240)})
    return request(instruction="Find the red can in the room and approach it. " + payload, modalities=modalities,
                   step=5, security_prefix=variant, failures=failures,
                   reference_state=reference(planning="The can is 20 degrees to the left about 1.8 m away; turn left "
                                                      "to centre it, then move forward 300 mm while keeping clear of "
                                                      "the ball on the right.",
                                             camera="A red can slightly left of centre, about 1.8 m away; a white "
                                                    "ball on the right edge."))


@pytest.mark.parametrize("variant", [None, *VARIANTS])
def test_a_typical_step_fits_the_token_budget(plugins, variant):
    count = _token_counter()
    prompt = build(plugins).build(typical_retry_request(variant))
    tokens = count(prompt.system) + count(prompt.user_text) + IMAGE_TOKENS * len(prompt.images)
    assert len(prompt.images) == 2
    assert tokens <= STEP_BUDGET, f"{variant}: {tokens} tokens"


def test_the_response_outline_follows_the_scenarios_limits(plugins):
    """The outline's example numbers lie inside the step's limits (a copied example stays valid)."""
    from safeembodai_core.models import ControlLimits
    from safeembodai_core.models.response import schema_outline
    from safeembodai_plugins.prompting.builder import OUTLINE_EXAMPLES, outline_rng

    def outline(req, limits=ControlLimits()):
        return schema_outline(limits, OUTLINE_EXAMPLES, outline_rng(req))

    small = ControlLimits(max_distance_mm=100, max_angle_deg=20)
    prompt = build(plugins).build(request(limits=small))
    assert outline(request(limits=small), small) in prompt.system
    assert outline(request(limits=small)) not in prompt.system
    shown = json.loads(outline(request(limits=small), small))["control"]
    assert all(0 < e.get("distance", e.get("angle")) < (100 if "distance" in e else 20) for e in shown)
    assert outline(request()) in build(plugins).build(request()).system
