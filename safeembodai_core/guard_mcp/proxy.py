"""Each tool call an agent makes, under the policy: read, judged, forwarded or refused, recorded.

:class:`GuardMcp` is guard-mcp without its transports: :meth:`GuardMcp.call` takes a tool's name and
arguments as the MCP client sent them and answers a ``CallToolResult``. A read-only tool goes to the
upstream and its result comes back as the upstream gave it. Everything else is read by
:func:`~.calls.read_call`; a motion is judged on the robot's own latest scan
(:class:`~.judging.MotionJudge`) and run in slices (:func:`~.slices.run_motion`); anything else the
policy allows is forwarded in its canonical form. A refusal is a tool error (``isError``) whose text
and ``structuredContent`` carry the reasons, the advice and the numbers, so the agent can amend, and
(``state_management``) R_{i-1}, the last calls that ran on the robot (:func:`~.agent.executed_state`).
What the upstream answers reaches the agent marked as untrusted data (``mark_untrusted``:
:func:`~.agent.mark_untrusted`).

Actuating calls run one at a time (a lock), however many the client sends at once. After
``failures.threshold`` refusals in a row, ``failures.then: stop_only`` answers only stops until
:meth:`GuardMcp.reset` (SIGHUP) or a restart; ``continue`` lets the agent go on. Every call leaves a
:class:`CallRecord` (the verdict, what ran, the robot's pose before and after) in :attr:`GuardMcp.calls`
and with ``on_call``, for a session's record (:mod:`.session`).
"""

from __future__ import annotations

import json
import time
from collections import deque
from typing import Any, Awaitable, Callable

import anyio
from mcp import types

from ..logs import get_logger
from ..trust.quoting import quote_untrusted
from .agent import admits_wrapper, executed_state, mark_untrusted
from .calls import CallRefused, Forward, Motion, read_call
from .judging import MotionJudge
from .policy import Policy
from .records import CallRecord
from .senses import Blind, RobotSenses
from .slices import Ran, run_motion

log = get_logger(__name__)
Upstream = Callable[[str, dict[str, Any]], Awaitable[types.CallToolResult]]


def _words(read: Motion | Forward) -> str:
    """The call as read, in words: a motion's messages with their durations, or the canonical arguments."""
    if isinstance(read, Forward):
        return f"{read.tool} {quote_untrusted(json.dumps(read.arguments, sort_keys=True, default=str), 300)}"
    holds = "; ".join(f"linear.x {h.twist.linear_x:g} m/s" + (f", linear.y {h.twist.linear_y:g} m/s"
                                                             if h.twist.linear_y else "")
                      + f", angular.z {h.twist.angular_z:g} rad/s" + ("" if read.kind == "publish_once"
                                                                       else f" for {h.duration_s:g} s")
                      for h in read.holds[:12])
    more = f"; and {len(read.holds) - 12} more" if len(read.holds) > 12 else ""
    return f"{read.tool} on {read.topic} ({read.msg_type}): {holds}{more}"


def _said(result: types.CallToolResult) -> str:
    """What an upstream's answer said, in short and quoted (for the record and R_{i-1})."""
    text = " ".join(getattr(part, "text", f"[{part.type}]") for part in result.content)
    return ("error: " if result.isError else "") + quote_untrusted(text, 300)


def _text(payload: dict[str, Any], error: bool) -> types.CallToolResult:
    return types.CallToolResult(content=[types.TextContent(type="text", text=json.dumps(payload, indent=1))],
                                structuredContent=payload, isError=error)


class GuardMcp:
    """The guarded tool calls (module docstring)."""

    def __init__(self, policy: Policy, judge: MotionJudge, senses: RobotSenses, upstream: Upstream,
                 robot: tuple[str, int], *, holonomic: bool = False,
                 on_call: Callable[[CallRecord], None] | None = None) -> None:
        self.policy, self.judge, self.senses, self.upstream = policy, judge, senses, upstream
        self.robot, self.holonomic, self.on_call = robot, holonomic, on_call
        self.slicer = next((tool for tool, kind in policy.tools.items() if kind == "publish_for_durations"), None)
        self.refusals_in_a_row = 0
        self.stop_only = False
        self.calls: deque[CallRecord] = deque(maxlen=1000)
        self.unwrapped: set[str] = set()
        self._lock = anyio.Lock()

    def know_tools(self, tools: list[types.Tool]) -> None:
        """The upstream's tools: those whose output schema would refuse the untrusted wrapper keep their
        structured content as it came (their text is marked all the same)."""
        self.unwrapped = {tool.name for tool in tools if not admits_wrapper(tool.outputSchema)}

    def last_executed(self) -> list[dict[str, Any]]:
        """R_{i-1}: the last calls that ran on the robot and what they did (:func:`~.agent.executed_state`)."""
        return executed_state(self.calls)

    def state_now(self) -> dict[str, Any]:
        """What the resource ``safeembodai://state/last`` says: R_{i-1}, the pose now, the refusals in a row."""
        pose = self.senses.pose
        return {"last_executed": self.last_executed(),
                "pose_now": None if pose is None else dict(zip(("x_mm", "y_mm", "heading_deg"),
                                                               (round(value, 1) for value in pose))),
                "refusals_in_a_row": self.refusals_in_a_row, "threshold": self.policy.failures.threshold,
                "stop_only": self.stop_only}

    def reset(self) -> None:
        """Clear the refusals in a row and ``stop_only`` (the operator's SIGHUP)."""
        self.refusals_in_a_row, self.stop_only = 0, False
        log.warning("guard_mcp.reset")

    async def call(self, tool: str, arguments: dict[str, Any] | None) -> types.CallToolResult:
        """Answer one ``tools/call`` (module docstring); never raises for what the agent sent."""
        started = time.perf_counter()
        record = CallRecord(time.time(), str(tool)[:128], quote_untrusted(arguments, 2000), "refused",
                            pose_before=self.senses.pose)
        record.kind = self.policy.tools.get(tool) if isinstance(tool, str) else None
        try:
            try:
                read = read_call(tool, arguments, self.policy, self.robot, holonomic=self.holonomic)
            except CallRefused as refused:
                return self._refuse(record, [refused.reason], [refused.advice] if refused.advice else [])
            record.words = _words(read)
            if isinstance(read, Forward) and not read.actuates:
                record.verdict = "read_only" if read.kind == "read_only" else "forwarded"
                return self._answer(record, await self.upstream(read.tool, read.arguments))
            async with self._lock:
                if self.stop_only and not (isinstance(read, Motion) and read.is_stop):
                    return self._refuse(record, [f"{self.refusals_in_a_row} refusals in a row reached the policy's "
                                                 f"threshold ({self.policy.failures.threshold}): only stops are "
                                                 "answered until guard-mcp is reset by its operator"], [],
                                        by="stop_only")
                if isinstance(read, Forward):
                    result = await self.upstream(read.tool, read.arguments)
                    record.verdict = "forwarded"
                    self.refusals_in_a_row = 0
                    return self._answer(record, result)
                return await self._move(read, record)
        finally:
            record.pose_after = self.senses.pose
            record.took_s = time.perf_counter() - started
            self.calls.append(record)
            if self.on_call is not None:
                self.on_call(record)

    def _answer(self, record: CallRecord, result: types.CallToolResult) -> types.CallToolResult:
        """The upstream's ``result``, recorded in short and marked untrusted (``mark_untrusted``)."""
        record.result = _said(result)
        if result.isError and record.verdict == "forwarded":
            record.verdict, record.by, record.reasons = "failed", "upstream", [f"the upstream answered {record.result}"]
        if not self.policy.mark_untrusted:
            return result
        return mark_untrusted(record.tool, result, wrap=record.tool not in self.unwrapped)

    async def _move(self, motion: Motion, record: CallRecord) -> types.CallToolResult:
        if self.slicer is None:
            return self._refuse(record, ["the policy maps no publish_for_durations tool to run motions with"], [])
        steps = self.judge.plan(motion)
        view = None
        if not motion.is_stop:
            try:
                view = self.senses.view()
            except Blind as blind:
                return self._refuse(record, [str(blind)], ["wait for the robot's scan, then ask again"], by="scan")
            if self.judge.mode == "refuse":
                judged = self.judge.judge(steps, view)
                if not judged.ok:
                    return self._refuse(record, judged.reasons, judged.advice, judged.safe, by="guard")
        ran = await run_motion(motion, steps, self.judge, self.senses, self._slice, slice_s=self.policy.slice_s,
                               stream_hz=self.policy.stream_hz, clock=self.senses.clock,
                               judged_on=view if self.judge.mode == "refuse" else None)
        record.ran, record.verdict, record.reasons, record.advice = ran.slices, ran.verdict, ran.reasons, ran.advice
        record.by = "upstream" if ran.verdict == "failed" else "guard"
        record.result = f"{ran.verdict}: {len(ran.slices)} slices over {ran.ran_s:g} s, {ran.published} published"
        if ran.verdict in ("stopped", "failed"):
            if not ran.slices:
                return self._refuse(record, ran.reasons, ran.advice, ran.safe, by=record.by)
            self.refusals_in_a_row += ran.verdict == "stopped"
            return _text(self._guard(ran, motion, refused=True), True)
        self.refusals_in_a_row = 0
        body = self._guard(ran, motion)
        if motion.kind == "publish_once":
            return _text({"success": True, "note": "published once (guard-mcp: judged, then sent at once)", **body},
                         False)
        return _text({"success": True, "published_count": ran.published, "total_messages": len(motion.holds),
                      "topic": motion.topic, "msg_type": motion.msg_type, "rate_hz": self.policy.stream_hz,
                      "errors": [], **body}, False)

    def _guard(self, ran: Ran, motion: Motion, refused: bool = False) -> dict[str, Any]:
        guard = {"verdict": ran.verdict, "ran_s": ran.ran_s, "slices": len(ran.slices), "reasons": ran.reasons}
        if ran.advice or ran.safe:
            guard.update(advice=ran.advice, safe=ran.safe)
        if not refused:
            return {"guard": guard}
        return {"refused": True, "tool": motion.tool, "guard": guard, **self._streak(), **self._state()}

    def _state(self) -> dict[str, Any]:
        return {"last_executed": self.last_executed()} if self.policy.state_management else {}

    async def _slice(self, arguments: dict[str, Any]) -> tuple[bool, Any]:
        assert self.slicer is not None
        result = await self.upstream(self.slicer, arguments)
        content = result.structuredContent if isinstance(result.structuredContent, dict) else {}
        if result.isError or "error" in content:
            text = " ".join(getattr(part, "text", "") for part in result.content)
            return False, quote_untrusted(content.get("error", text), 300)
        count = content.get("published_count")
        return True, count if isinstance(count, int) and not isinstance(count, bool) else 1

    def _streak(self) -> dict[str, Any]:
        threshold = self.policy.failures.threshold
        if self.refusals_in_a_row >= threshold and self.policy.failures.then == "stop_only" and not self.stop_only:
            self.stop_only = True
            log.warning("guard_mcp.stop_only", refusals=self.refusals_in_a_row)
        return {"refusals_in_a_row": self.refusals_in_a_row, "threshold": threshold, "stop_only": self.stop_only}

    def _refuse(self, record: CallRecord, reasons: list[str], advice: list[str],
                safe: dict[str, Any] | None = None, by: str = "policy") -> types.CallToolResult:
        record.verdict, record.reasons, record.advice, record.by = "refused", reasons, advice, by
        self.refusals_in_a_row += 1
        log.info("guard_mcp.refused", tool=record.tool, reasons=reasons[:3])
        payload = {"refused": True, "tool": record.tool, "reasons": reasons, "advice": advice, "safe": safe or {},
                   **self._streak(), **self._state()}
        return _text(payload, True)
