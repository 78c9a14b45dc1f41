"""``LLMAgent``: an LLM (any registered backend) acting in a ``action_format="text"`` env.

It does what the guarded loop does around the backend, from the observation alone: the
perception plugin renders the camera image and the LiDAR picture, the prompt builder writes the
paper's prompt (with the security prefix when ``security_prefix`` is set) and the backend's whole
reply -- its text, finish reason, reasoning, number of choices and what the backend's strict reading
of the envelope found -- is the action. A refusal's feedback that came back in ``info`` (the failure
lines, and the same as data with each rule's advice) goes into the next prompt with the step's earlier
ones, as Algorithm 1 feeds them back in the trial loop. The env then reads the reply exactly as the loop does
(:func:`~safeembodai_core.models.read_reply`): an answer cut off at the token limit, filtered, or
with a second plan in its reasoning is refused there as here, however complete its text; wrap the env
in :class:`SafeEmbodAIGuard` for the validators. The reference state R_{i-1} is not sent (an
agent keeps its own memory).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ... import seeds
from ...plugin.building import build_components
from ...models import DEFAULT_LIMITS, ControlLimits, LidarScan, Observation, PromptRequest, Refusal
from ...models.reply import BackendReply, as_reply
from ...models.prompt import DEFAULT_TASK
from ...plugin.manager import Plugins, load_plugins


class LLMAgent:
    """``act(obs, info) -> BackendReply``: the backend's whole reply to the prompt of this observation.

    ``backend``, ``perception`` and ``prompt_builder`` are registered names (with options) or
    objects, as for :func:`~safeembodai_core.run_guarded_trial`; ``max_range_mm`` is the LiDAR's
    range (the observation's ``lidar`` high bound), ``seed`` the backend's random stream.
    """

    def __init__(self, backend: Any = "mock", *, max_range_mm: float, perception: Any = "images",
                 prompt_builder: Any = "jinja", security_prefix: str | None = None, task: str = DEFAULT_TASK,
                 limits: ControlLimits = DEFAULT_LIMITS, seed: int = 0, plugins: Plugins | None = None) -> None:
        plugins = plugins or load_plugins()
        self.backend = build_components(plugins, "llm_backend", [backend], seed)[0][1]
        self.perception = build_components(plugins, "perception", [perception], seed)[0][1]
        self.builder = build_components(plugins, "prompt_builder", [prompt_builder], seed)[0][1]
        self.max_range_mm, self.security_prefix, self.task, self.limits = max_range_mm, security_prefix, task, limits
        self.seed, self.calls = seed, 0
        #: the step the feedback below is for, and Algorithm 1's feedback so far at it (lines and data)
        self._step: int | None = None
        self._failures: list[str] = []
        self._refusals: list[Refusal] = []

    def act(self, obs: dict[str, Any], info: dict[str, Any]) -> BackendReply:
        """The backend's reply, whole: hand it to ``env.step`` as it is (not its ``text``: the
        finish reason and the reasoning are part of what is judged)."""
        ranges = np.asarray(obs["lidar"], dtype=float)
        ranges = np.where(ranges >= self.max_range_mm, np.inf, ranges)  # the Box's "no return" back to inf
        observation = Observation(camera=obs.get("camera"), lidar=LidarScan(ranges, self.max_range_mm))
        if info["step"] != self._step:  # a new step: nothing refused yet
            self._step, self._failures, self._refusals = info["step"], [], []
        if info.get("refused") and info.get("attempt", 0) > 0:  # a retry: the refusal's feedback, as the loop's
            self._failures += info.get("feedback") or info.get("reasons", [])
            self._refusals += [Refusal.model_validate(r) for r in info.get("refusals", ())]
        request = PromptRequest(
            instruction=obs["instruction"], modalities=self.perception.perceive(observation), step=info["step"],
            security_prefix=self.security_prefix, failures=tuple(self._failures), refusals=tuple(self._refusals),
            limits=self.limits, task=self.task)
        self.calls += 1
        return as_reply(self.backend.complete(self.builder.build(request), seeds.rng(self.seed, "agent", self.calls)))

    def close(self) -> None:
        self.backend.close()
