"""The pilot as a tool-calling agent: the scenario's backend plans, its plans become motion calls.

:class:`PilotDecider` wraps any :class:`~safeembodai_core.contracts.components.LLMBackend` that answers the
paper's prompt (the offline mock pilot by default) as an MCP agent. Each step it

1. **observes** through the read tools: ``subscribe_once`` on the scan, the camera and the text the
   camera reads (each as the served room names it; one that fails is left out, as a lost sensor);
2. **decides**: the readings become an :class:`~safeembodai_core.models.Observation`, the scenario's
   perception and prompt builder make the prompt -- the step's human instruction, then what the
   camera reads after "The camera reads:" (the pilot reads both as text in its prompt, as an LLM
   reads a tool result in its context) -- and the backend answers a plan (read strictly, as the trial
   loop reads it);
3. **acts**: the plan as one ``publish_for_durations`` call (:func:`~.motions.motion_arguments`);
4. **reads the result**: a refusal (guard-mcp's tool error) becomes the core's
   :class:`~safeembodai_core.models.Refusal`, its numbers for the pilot and its words for the prompt,
   and the step is asked again -- Algorithm 1's retry, up to ``failure_threshold`` times, with the
   trial loop's feedback lines and the trial loop's dice (``seeds.rng(seed, "backend", step, attempt)``).

The security prefix: an MCP client puts the server's ``instructions`` before its model's context.
When they carry one of the prompt builder's security prefixes (guard-mcp's policy
``security_prefix``), the pilot's prompt is built with that prefix, which is how the pilot knows it
is there (``Prompt.sections``). Nothing else of the server's instructions reaches the pilot; nor does
guard-mcp's R_{i-1}: the pilot reads its reference state only from the prompt builder's own section.
"""

from __future__ import annotations

import asyncio
import time
from dataclasses import replace
from typing import Any

from .. import seeds
from ..contracts.components import LLMBackend, Perception, PromptBuilder
from ..errors import BackendError
from ..logs import get_logger, redact
from ..loop.guarded_step import feedback, feedback_refusals
from ..models import Attempt, Observation, PromptRequest, Refusal, ResponseParseError, read_reply
from ..models.reply import as_reply, finish_reason_text
from .loop import AgentTask, StepInput, StepReport
from .motions import motion_arguments, refusal_body, runs_s, stop_only, verdict
from .readings import NotRead, camera_frame, camera_text, laser_scan
from .tools import McpTools

log = get_logger(__name__)

MAX_STORED_TEXT = 16_000
LASER_SCAN = "sensor_msgs/msg/LaserScan"
COMPRESSED_IMAGE = "sensor_msgs/msg/CompressedImage"
STRING = "std_msgs/msg/String"
#: Put between the human instruction and what the camera reads, in the pilot's instruction.
CAMERA_READS = " The camera reads: "


def prefix_variant(instructions: str | None, builder: PromptBuilder) -> str | None:
    """The security-prefix variant whose text ``instructions`` carry (the longest such text; the first the
    builder lists among equals), or None."""
    if not instructions:
        return None
    said = " ".join(instructions.split())
    found: tuple[int, str] | None = None
    for variant in builder.security_prefix_variants() or []:
        try:
            text = builder.security_prefix(variant)
        except Exception:  # a variant that cannot stand alone (it fences the instruction): not this one
            continue
        text = " ".join((text or "").split())
        if text and text in said and (found is None or len(text) > found[0]):
            found = (len(text), variant)
    return found[1] if found else None


def pilot_instruction(instruction: str, read: str) -> str:
    """The instruction the pilot is given: the human's, then what the camera reads (when it reads anything)."""
    read = " ".join(read.split())
    return f"{instruction}{CAMERA_READS}{read}" if read else instruction


class PilotDecider:
    """The scenario's backend as an MCP agent (module docstring)."""

    def __init__(self, backend: LLMBackend, perception: Perception, builder: PromptBuilder) -> None:
        self.backend, self.perception, self.builder = backend, perception, builder
        self.task = AgentTask()
        self.variant: str | None = None

    async def begin(self, tools: McpTools, task: AgentTask) -> None:
        self.task = task
        self.variant = prefix_variant(tools.instructions, self.builder)

    def close(self) -> None:
        self.backend.close()

    async def observe(self, tools: McpTools) -> tuple[Observation, str]:
        """The scan, the camera frame and the text the camera reads, each as far as it could be read."""
        topics = self.task.topics
        observation, read = Observation(), ""
        try:
            observation.lidar = laser_scan(await tools.call("subscribe_once", {"topic": topics.scan,
                                                                               "msg_type": LASER_SCAN}))
        except NotRead as failure:
            log.info("mcp_agent.no_scan", why=str(failure))
        try:
            observation.camera = camera_frame(await tools.call(
                "subscribe_once", {"topic": topics.camera, "msg_type": COMPRESSED_IMAGE, "expects_image": "true"}))
        except NotRead as failure:
            log.info("mcp_agent.no_camera", why=str(failure))
        if topics.camera_text:
            try:
                read = camera_text(await tools.call("subscribe_once", {"topic": topics.camera_text,
                                                                       "msg_type": STRING}))
            except NotRead as failure:
                log.info("mcp_agent.no_camera_text", why=str(failure))
        return observation, read

    async def step(self, tools: McpTools, given: StepInput) -> StepReport:
        observation, read = await self.observe(tools)
        report = StepReport(given.step, given.instruction, camera_text=read)
        request = PromptRequest(instruction=pilot_instruction(given.instruction, read),
                                modalities=self.perception.perceive(observation), step=given.step,
                                security_prefix=self.variant, limits=self.task.limits, task=self.task.task)
        failures: list[str] = []
        refusals: list[Refusal] = []
        for index in range(self.task.failure_threshold + 1):
            attempt = await self._ask(request, failures, refusals, given.seed, index)
            report.attempts.append(attempt)
            if attempt.response is not None:
                plan = list(attempt.response.control)
                if not plan:
                    return report  # nothing to run: the step ends standing
                arguments = motion_arguments(plan, self.task.speeds, topic=self.task.topics.cmd_vel)
                outcome = await tools.call("publish_for_durations", arguments, runs_s(arguments))
                body = refusal_body(outcome.content) if outcome.error else None
                if not outcome.error and not _failed(outcome.content):
                    report.planned = plan
                    return report
                if body is None:
                    report.ended, report.detail = "error", f"publish_for_durations failed: {outcome.text[:300]}"
                    return report
                refused = verdict(body, plan)
                attempt.verdicts = [refused]
                report.refused += 1
                report.notes.append(refused.reason[:500])
                if stop_only(body):
                    report.ended = "safe_abort"
                    report.detail = "the MCP server answers only stops: its failure threshold was reached"
                    return report
            failures.extend(feedback(index, attempt))
            refusals.extend(feedback_refusals(index, attempt))
        report.ended = "safe_abort"
        report.detail = f"no plan of step {given.step} was run after {self.task.failure_threshold} retries"
        return report

    async def _ask(self, request: PromptRequest, failures: list[str], refusals: list[Refusal], seed: int,
                   index: int) -> Attempt:
        prompt = self.builder.build(replace(request, failures=tuple(failures), refusals=tuple(refusals)))
        rng = seeds.rng(seed, "backend", request.step, index)
        sampling = self.backend.prepare_attempt(index=index, limits=request.limits, rng=rng)
        started = time.perf_counter()
        try:
            reply = as_reply(await asyncio.to_thread(self.backend.complete, prompt, rng))
        except BackendError as error:
            return Attempt(index=index, parse_error=f"the backend gave no answer: {error}"[:2000])
        attempt = Attempt(index=index, raw_text=_stored(reply.text), reasoning=_stored(reply.reasoning),
                          model=_stored(reply.model)[:200] or None, usage=reply.usage,
                          latency_s=reply.latency_s or (time.perf_counter() - started),
                          finish_reason=finish_reason_text(reply.finish_reason), sampling=sampling or None)
        try:
            attempt.response = read_reply(reply, request.limits)
        except ResponseParseError as error:
            attempt.parse_error = str(error)
        return attempt


def _failed(content: Any) -> bool:
    """ros-mcp answers a failure it met as a result that says ``error`` (not as a tool error)."""
    return isinstance(content, dict) and "error" in content and content.get("success") is not True


def _stored(text: object) -> str:
    return redact(text)[:MAX_STORED_TEXT] if isinstance(text, str) else ""
