"""Each tool call an agent makes, under the policy: read, judged, forwarded or refused, recorded.

:class:`GuardMcp` is guard-mcp without its transports: :meth:`GuardMcp.call` takes a tool's name and
arguments as the MCP client sent them and answers a ``CallToolResult``. A read-only tool goes to the
upstream and its result comes back as the upstream gave it. Everything else is read by
:func:`~.calls.read_call`; a motion is judged on the robot's own latest scan
(:class:`~.judging.MotionJudge`) and run in slices (:func:`~.slices.run_motion`); anything else the
policy allows is forwarded in its canonical form. A refusal is a tool error (``isError``) whose text
and ``structuredContent`` carry the reasons, the advice and the numbers, so the agent can amend.

Actuating calls run one at a time (a lock), however many the client sends at once. After
``failures.threshold`` refusals in a row, ``failures.then: stop_only`` answers only stops until
:meth:`GuardMcp.reset` (SIGHUP) or a restart; ``continue`` lets the agent go on. Every call leaves a
:class:`CallRecord` (the verdict, what ran, the robot's pose before and after) in :attr:`GuardMcp.calls`
and with ``on_call``, for a session's record.
"""

from __future__ import annotations

import json
import time
from collections import deque
from dataclasses import dataclass, field
from typing import Any, Awaitable, Callable

import anyio
from mcp import types

from ..logs import get_logger
from ..quoting import quote_untrusted
from .calls import CallRefused, Forward, Motion, read_call
from .judging import MotionJudge
from .policy import Policy
from .senses import Blind, RobotSenses
from .slices import Ran, run_motion

log = get_logger(__name__)
Upstream = Callable[[str, dict[str, Any]], Awaitable[types.CallToolResult]]


@dataclass
class CallRecord:
    """One call: what was asked, the ``verdict`` (``read_only``, ``forwarded``, ``limited``, ``refused``,
    ``stopped``, ``failed``), why, what ran, the robot's odometry pose before and after."""

    time_s: float
    tool: str
    arguments: str
    verdict: str
    reasons: list[str] = field(default_factory=list)
    ran: list[list[float]] = field(default_factory=list)
    pose_before: tuple[float, float, float] | None = None
    pose_after: tuple[float, float, float] | None = None


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
        self._lock = anyio.Lock()

    def reset(self) -> None:
        """Clear the refusals in a row and ``stop_only`` (the operator's SIGHUP)."""
        self.refusals_in_a_row, self.stop_only = 0, False
        log.warning("guard_mcp.reset")

    async def call(self, tool: str, arguments: dict[str, Any] | None) -> types.CallToolResult:
        """Answer one ``tools/call`` (module docstring); never raises for what the agent sent."""
        record = CallRecord(time.time(), str(tool)[:128], quote_untrusted(arguments, 2000), "refused",
                            pose_before=self.senses.pose)
        try:
            try:
                read = read_call(tool, arguments, self.policy, self.robot, holonomic=self.holonomic)
            except CallRefused as refused:
                return self._refuse(record, [refused.reason], [refused.advice] if refused.advice else [])
            if isinstance(read, Forward) and not read.actuates:
                record.verdict = "read_only" if read.kind == "read_only" else "forwarded"
                return await self.upstream(read.tool, read.arguments)
            async with self._lock:
                if self.stop_only and not (isinstance(read, Motion) and read.is_stop):
                    return self._refuse(record, [f"{self.refusals_in_a_row} refusals in a row reached the policy's "
                                                 f"threshold ({self.policy.failures.threshold}): only stops are "
                                                 "answered until guard-mcp is reset by its operator"], [])
                if isinstance(read, Forward):
                    result = await self.upstream(read.tool, read.arguments)
                    record.verdict = "forwarded"
                    self.refusals_in_a_row = 0
                    return result
                return await self._move(read, record)
        finally:
            record.pose_after = self.senses.pose
            self.calls.append(record)
            if self.on_call is not None:
                self.on_call(record)

    async def _move(self, motion: Motion, record: CallRecord) -> types.CallToolResult:
        if self.slicer is None:
            return self._refuse(record, ["the policy maps no publish_for_durations tool to run motions with"], [])
        steps = self.judge.plan(motion)
        if not motion.is_stop:
            try:
                view = self.senses.view()
            except Blind as blind:
                return self._refuse(record, [str(blind)], ["wait for the robot's scan, then ask again"])
            if self.judge.mode == "refuse":
                judged = self.judge.judge(steps, view)
                if not judged.ok:
                    return self._refuse(record, judged.reasons, judged.advice, judged.safe)
        ran = await run_motion(motion, steps, self.judge, self.senses, self._slice, slice_s=self.policy.slice_s,
                               stream_hz=self.policy.stream_hz, clock=self.senses.clock)
        record.ran, record.verdict, record.reasons = ran.slices, ran.verdict, ran.reasons
        if ran.verdict in ("stopped", "failed"):
            if not ran.slices:
                return self._refuse(record, ran.reasons, ran.advice, ran.safe)
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
        return {"refused": True, "tool": motion.tool, "guard": guard, **self._streak()} if refused else {"guard": guard}

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
                safe: dict[str, Any] | None = None) -> types.CallToolResult:
        record.verdict, record.reasons = "refused", reasons
        self.refusals_in_a_row += 1
        log.info("guard_mcp.refused", tool=record.tool, reasons=reasons[:3])
        payload = {"refused": True, "tool": record.tool, "reasons": reasons, "advice": advice, "safe": safe or {},
                   **self._streak()}
        return _text(payload, True)
