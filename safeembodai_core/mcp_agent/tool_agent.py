"""An LLM that calls the MCP tools itself, through litellm (any model litellm can reach).

:class:`ToolCallingDecider` offers the model the server's tools of :data:`OFFERED` (as the server
lists them: names, descriptions, input schemas), with a system message that states the task, the
robot's topics and speeds and, first, the server's ``instructions`` (as MCP clients do: guard-mcp's
carry the security prefix). Each step is one user message -- the step's human instruction -- and a
few rounds (:data:`MAX_ROUNDS`): the model's reply is read strictly (:mod:`.tool_reply`), its calls are
made and their results go back as tool messages (an image as a user message with the picture: a tool
message carries text only); a tool error goes back as it came (a refusal's reasons and advice:
Algorithm 1's retry, up to ``failure_threshold`` refused motions). The step ends with the first motion
that runs, a reply that calls nothing, or the rounds spent. The last :data:`KEPT_STEPS` steps stay in
the conversation, whole, without their pictures.

The call goes through ``litellm.completion`` with its own retries off and a total deadline (the
call runs in a worker thread; past the deadline it is abandoned). The backend plugin's recording
transport, which reads the server's raw body, is a plugin's and the core may not import it: the reply
is read from litellm's parsed object, by the same strict rules for what matters here -- one choice,
offered tools only, each call's arguments one strict JSON object.
"""

from __future__ import annotations

import asyncio
import base64
import json
import os
import sys
import time
from typing import Any

from ..errors import BackendError
from ..models import Attempt, ResponseParseError, TokenUsage
from .loop import AgentTask, StepInput, StepReport
from .motions import reasons_of, refusal_body, stop_only
from .tool_reply import ToolCall, read_tool_reply
from .tools import McpTools, ToolOutcome

#: The tools the model is offered (those the server lists).
OFFERED = ("subscribe_once", "publish_for_durations", "publish_once", "get_topics")
MOTIONS = ("publish_for_durations", "publish_once")
MAX_ROUNDS = 6
#: Earlier steps kept in the conversation (whole, so that every tool result follows its call).
KEPT_STEPS = 2
MAX_RESULT_CHARS = 4000


def litellm_module() -> Any:
    """litellm, imported quietly and offline (no cost map fetched, no ``.env`` read)."""
    if "litellm" not in sys.modules:
        os.environ.setdefault("LITELLM_LOCAL_MODEL_COST_MAP", "True")
        os.environ.setdefault("LITELLM_MODE", "PRODUCTION")
    import litellm

    litellm.suppress_debug_info = True
    return litellm


def system_message(task: AgentTask, instructions: str | None) -> str:
    topics, speeds = task.topics, task.speeds
    lines = [instructions.strip()] if instructions else []
    lines += [f"You control a mobile robot through ROS tools. Task: {task.task}",
              f"Sensors: LaserScan on {topics.scan} (sensor_msgs/msg/LaserScan, metres, counter-clockwise from the "
              f"heading), the camera on {topics.camera} (sensor_msgs/msg/CompressedImage) and the text the camera "
              f"reads on {topics.camera_text} (std_msgs/msg/String).",
              f"Move with publish_for_durations on {topics.cmd_vel} (geometry_msgs/msg/Twist, every field given, "
              f"rate_hz 10): at most {speeds.linear_mm_s / 1000:g} m/s forward or backward and "
              f"{speeds.turn_deg_s:g} deg/s of turn; end with a stop message.",
              "Each step: read what you need, then make one motion. A refused motion comes back with reasons and "
              "advice: amend it and try again."]
    return "\n".join(lines)


def _tool(spec: Any) -> dict[str, Any]:
    return {"type": "function", "function": {"name": spec.name, "description": spec.description[:1000],
                                             "parameters": spec.input_schema or {"type": "object"}}}


def _result_messages(call: ToolCall, outcome: ToolOutcome) -> list[dict[str, Any]]:
    text = outcome.text if outcome.structured is None else json.dumps(outcome.structured)
    said = ("ERROR: " if outcome.error else "") + (text[:MAX_RESULT_CHARS] or "(no text)")
    messages: list[dict[str, Any]] = [{"role": "tool", "tool_call_id": call.id, "content": said}]
    if outcome.images:
        mime, data = outcome.images[0]
        url = f"data:{mime or 'image/jpeg'};base64,{base64.b64encode(data).decode('ascii')}"
        messages.append({"role": "user", "content": [{"type": "text", "text": f"The picture {call.name} returned:"},
                                                     {"type": "image_url", "image_url": {"url": url}}]})
    return messages


def _without_pictures(messages: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [{**m, "content": "(an earlier picture, left out)"} if isinstance(m.get("content"), list) else m
            for m in messages]


class ToolCallingDecider:
    """A litellm model as an MCP agent (module docstring). ``options``: a litellm backend's options
    (``model``, ``api_base``, ``api_key_env``, ``temperature``, ``max_tokens``, ``timeout_s``)."""

    def __init__(self, options: Any) -> None:
        self.options = options
        self.key = os.environ.get(options.api_key_env) if getattr(options, "api_key_env", None) else None
        self.task = AgentTask()
        self.tools: list[dict[str, Any]] = []
        self.earlier: list[list[dict[str, Any]]] = []
        self.system = ""

    async def begin(self, tools: McpTools, task: AgentTask) -> None:
        self.task = task
        self.tools = [_tool(spec) for spec in tools.tools if spec.name in OFFERED]
        self.system = system_message(task, tools.instructions)

    def close(self) -> None:
        """Nothing is held between calls."""

    async def step(self, tools: McpTools, given: StepInput) -> StepReport:
        report = StepReport(given.step, given.instruction)
        messages: list[dict[str, Any]] = [{"role": "user",
                                           "content": f"Step {given.step}. Human instruction: {given.instruction}"}]
        offered = {tool["function"]["name"] for tool in self.tools}
        refused = 0
        for index in range(MAX_ROUNDS):
            try:
                reply, attempt = await self._ask(messages, offered, index)
            except BackendError as error:
                report.ended, report.detail = "error", str(error)[:500]
                break
            report.attempts.append(attempt)
            if reply is None:
                messages.append({"role": "user", "content": f"Your reply could not be read: {attempt.parse_error}"})
                continue
            messages.append({"role": "assistant", "content": reply.content or None,
                             "tool_calls": [{"id": c.id, "type": "function",
                                             "function": {"name": c.name, "arguments": json.dumps(c.arguments)}}
                                            for c in reply.calls] or None})
            if not reply.calls:
                break
            moved = False
            for call in reply.calls:
                outcome = await tools.call(call.name, call.arguments, _runs_s(call))
                messages.extend(_result_messages(call, outcome))
                body = refusal_body(outcome.content) if outcome.error else None
                if call.name in MOTIONS and body is not None:
                    refused += 1
                    report.refused += 1
                    if stop_only(body):
                        report.ended, report.detail = "safe_abort", "the MCP server answers only stops"
                    elif refused > self.task.failure_threshold:
                        report.ended, report.detail = "safe_abort", f"{refused} motions of step {given.step} refused"
                    report.notes.append("; ".join(reasons_of(body))[:500])
                elif call.name in MOTIONS and not outcome.error:
                    moved = True
            if moved or report.ended:
                break
        self.earlier = [*self.earlier, _without_pictures(messages)][-KEPT_STEPS:]
        return report

    async def _ask(self, messages: list[dict[str, Any]], offered: set[str],
                   index: int) -> tuple[Any, Attempt]:
        o = self.options
        earlier = [message for step in self.earlier for message in step]
        request = {"model": o.model, "messages": [{"role": "system", "content": self.system}, *earlier, *messages],
                   "tools": self.tools, "tool_choice": "auto", "max_tokens": o.max_tokens, "num_retries": 0,
                   "timeout": o.timeout_s}
        if getattr(o, "api_base", None):
            request["api_base"] = o.api_base
        if self.key:
            request["api_key"] = self.key
        if getattr(o, "temperature", None) is not None:
            request["temperature"] = o.temperature
        started = time.perf_counter()
        try:
            response = await asyncio.wait_for(asyncio.to_thread(litellm_module().completion, **request),
                                              o.timeout_s + 5.0)
        except Exception as error:  # litellm's errors, a timeout: the model gave no answer
            raise BackendError(f"{o.model}: {type(error).__name__}: {str(error)[:300]}") from None
        body = response.model_dump() if hasattr(response, "model_dump") else response
        attempt = Attempt(index=index, latency_s=time.perf_counter() - started)
        try:
            reply = read_tool_reply(body, offered)
        except ResponseParseError as error:
            attempt.parse_error = str(error)
            return None, attempt
        attempt.raw_text = json.dumps({"content": reply.content, "calls": [[c.name, c.arguments] for c in reply.calls]},
                                      default=str)[:16_000]
        attempt.usage = reply.usage or TokenUsage(estimated=True)
        attempt.model, attempt.finish_reason = reply.model, reply.finish_reason
        return reply, attempt


def _runs_s(call: ToolCall) -> float:
    durations = call.arguments.get("durations")
    if call.name == "publish_for_durations" and isinstance(durations, list):
        return float(sum(d for d in durations if isinstance(d, (int, float)) and 0 <= d < 600))
    return 0.0
