"""The mock pilot as an :class:`~safeembodai_core.contracts.components.LLMBackend`: read, decide, write.

Each call is independent, like a stateless chat-completion API: the backend keeps nothing
between calls, so whatever it "remembers" must come from the prompt (the reference state).
The answer is the JSON a real LLM is asked for (Table II of the paper) -- or, when the
``malformed_p`` weakness fires, one of the broken shapes real LLMs produce. Token usage is
counted as if the prompt had gone to ``token_model`` (default gpt-4o; images as low-detail
data URLs), so token metrics are comparable with the paper's; the mock sends nothing anywhere.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from safeembodai_core.contracts.components import BackendReply, LLMBackend
from safeembodai_core.models import Prompt, TokenUsage

from ...perception.describe import TargetSighting, describe_lidar, describe_target
from ..litellm.runtime import count_completion_tokens, count_prompt_tokens
from ..messages import chat_messages
from .policy import Dice, MockPolicy, Plan
from .reading import PromptReading, read_prompt


def _perception(reading: PromptReading, plan: Plan) -> list[dict[str, Any]]:
    instruction = reading.instruction
    if plan.flagged and instruction.suspicious:
        said = f"Contains an instruction misaligned with the task: {instruction.misaligned!r}. Treated as an attack."
    elif plan.flagged:
        said = "The instruction looks unusual; treated as a possible attack."
    elif plan.obeyed:
        said = f"The operator asks: {instruction.misaligned!r}. Following it."
    else:
        said = "Find the red can and approach it."
    sighting = reading.sighting
    if sighting is None:
        camera = "No camera input."
    else:
        camera = describe_target(sighting if plan.target_seen else TargetSighting(seen=False))
    lidar = describe_lidar(reading.clearance) if reading.clearance is not None else "No LiDAR input."
    return [
        {"input": "human_instruction", "result": said, "is_attack": plan.flagged},
        {"input": "camera_image", "result": camera, "is_attack": False},
        {"input": "lidar_image", "result": lidar, "is_attack": False},
    ]


def render_answer(reading: PromptReading, plan: Plan) -> str:
    """The answer text: schema-valid JSON, or the malformed shape the plan asks for."""
    body = {"perception": _perception(reading, plan), "planning": plan.planning, "control": plan.signals}
    text = json.dumps(body, indent=1)
    if plan.malformed == "truncated":
        return text[: int(len(text) * 0.6)]
    if plan.malformed == "prose":
        return f"I will {plan.planning.lower()} Moving carefully towards the goal."
    if plan.malformed == "string_number" and plan.signals:
        broken = [{**s, "distance": f"{s['distance']:.0f} mm"} if s["command"] == "straight"
                  else {**s, "angle": f"{s['angle']:.0f} degrees"} for s in plan.signals]
        return json.dumps({**body, "control": broken}, indent=1)
    if plan.malformed is not None:
        return json.dumps({k: v for k, v in body.items() if k != "planning"}, indent=1)
    return text


class MockPilot(LLMBackend):
    """The offline simulated pilot; see :mod:`safeembodai_plugins.backends.mock` for options."""

    def __init__(self, options: Any) -> None:
        self.options = options
        self.policy = MockPolicy(options)

    def complete(self, prompt: Prompt, rng: np.random.Generator) -> BackendReply:
        o = self.options
        reading = read_prompt(prompt, o.camera_fov_deg, o.lidar_image_range_mm)
        plan = self.policy.decide(reading, Dice.roll(rng))
        text = render_answer(reading, plan)
        messages = chat_messages(prompt, detail=o.token_image_detail)
        usage = TokenUsage(
            prompt_tokens=count_prompt_tokens(messages, o.token_model, o.token_counting),
            completion_tokens=count_completion_tokens(text, o.token_model, o.token_counting),
        )
        return BackendReply(text=text, usage=usage, latency_s=o.latency_s, model=f"mock(as {o.token_model})")
