"""A judged motion run through the upstream in slices, each re-judged on the newest scan.

A motion is not judged once and then left to run blind while the movers move. :func:`run_motion`
keeps the motion's own timeline on this machine's clock (message ``k`` ends ``sum(durations[:k+1])``
seconds after the first slice went out) and forwards it as calls of the upstream's
``publish_for_durations`` of one message each, at most ``slice_s`` long, streamed at ``stream_hz``
(what is judged, each message held for its duration, is what runs, whatever ``rate_hz`` the agent
gave). Before each slice the rest of the plan over the judge's window is judged on the newest scan
from where odometry says the robot is (:meth:`~.judging.MotionJudge.ahead`), unless the whole plan was
just judged on that very view (``judged_on``: the first slice, when no scan or odometry came since);
in ``mode: limit`` the slice's message is slowed instead. A slice refused, a scan gone stale, an upstream error or a
cancellation ends the motion with a stop published at once on guard-mcp's own rosbridge connection.

A message of duration 0 is superseded at once and not sent, unless it is the last: then it is
published once (the base holds it for its ``cmd_vel_timeout``), as is ``publish_once``'s message.
Slices are sent with the upstream's ``publish_for_durations`` (``rate_hz`` 0 for a single publish),
which publishes at once; ros-mcp's ``publish_once`` waits a second between advertising and publishing,
a second the judgement would age by.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any, Awaitable, Callable

from ..ros.twist import Twist
from .calls import Motion
from .judging import STOP, Judgement, MotionJudge, Step
from .senses import Blind, RobotSenses, View

#: The shortest slice sent: less of a message's time left is left to the base's hold.
MIN_SLICE_S = 0.02
UpstreamCall = Callable[[dict[str, Any]], Awaitable[tuple[bool, Any]]]


@dataclass
class Ran:
    """What a motion did: ``verdict`` (``forwarded``, ``limited``, ``stopped`` or ``failed``), each
    slice sent as ``[linear_x, angular_z, seconds]``, publishes counted by the upstream, and why."""

    verdict: str = "forwarded"
    slices: list[list[float]] = field(default_factory=list)
    published: int = 0
    reasons: list[str] = field(default_factory=list)
    advice: list[str] = field(default_factory=list)
    safe: dict[str, Any] = field(default_factory=dict)
    ran_s: float = 0.0


def _message(template: dict[str, Any], twist: Twist) -> dict[str, Any]:
    body = {"linear": {"x": twist.linear_x, "y": twist.linear_y, "z": 0.0},
            "angular": {"x": 0.0, "y": 0.0, "z": twist.angular_z}}
    return {"header": template["header"], "twist": body} if "twist" in template else body


async def run_motion(motion: Motion, steps: list[Step], judge: MotionJudge, senses: RobotSenses,
                     send: UpstreamCall, *, slice_s: float, stream_hz: float,
                     clock: Callable[[], float] = time.monotonic, judged_on: View | None = None) -> Ran:
    """Run ``motion`` (judged as ``steps``, on ``judged_on`` if given) in slices through ``send`` (module
    docstring)."""
    ran, start = Ran(), clock()
    ends, total = [], 0.0
    for hold in motion.holds:
        total += hold.duration_s
        ends.append(total)
    last = len(motion.holds) - 1
    try:
        for k, hold in enumerate(motion.holds):
            once = hold.duration_s == 0
            if once and k != last:
                continue
            while True:
                now = clock()
                left = start + ends[k] - now
                if not once and left < MIN_SLICE_S:
                    break
                seconds = 0.0 if once else min(slice_s, left)
                twist = hold.twist
                if twist != STOP:
                    view = senses.view(now)
                    if judge.mode == "limit":
                        judged = judge.limit(twist, view)
                        if judged.ok and judged.factor < 1.0:
                            twist, ran.verdict = twist.scaled(judged.factor), "limited"
                            ran.reasons = ran.reasons or judged.reasons
                    elif _same(view, judged_on) and not ran.slices:
                        judged = Judgement(True)  # the whole plan passed on this very view a moment ago
                    else:
                        judged = judge.judge(judge.ahead(steps, now - start), view)
                    if not judged.ok:
                        _stopped(ran, motion, senses, now - start, judged.reasons, judged.advice)
                        ran.safe = judged.safe
                        return ran
                ok, reply = await send({"topic": motion.topic, "msg_type": motion.msg_type,
                                        "messages": [_message(hold.message, twist)], "durations": [seconds],
                                        "rate_hz": 0 if once else stream_hz})
                ran.slices.append([twist.linear_x, twist.angular_z, round(seconds, 3)])
                if not ok:
                    _stopped(ran, motion, senses, clock() - start, [f"the upstream failed a slice: {reply}"], [])
                    ran.verdict = "failed"
                    return ran
                ran.published += int(reply) if isinstance(reply, int) else 1
                if once:
                    break
    except Blind as blind:
        _stopped(ran, motion, senses, clock() - start, [str(blind)], ["wait for the robot's scan, then ask again"])
    except BaseException:  # cancelled (guard-mcp ends) or failed: the base gets a stop whatever happened
        senses.stop(motion.topic, motion.msg_type)
        raise
    ran.ran_s = round(clock() - start, 3)
    return ran


def _same(view: View, judged_on: View | None) -> bool:
    return judged_on is not None and view.scan is judged_on.scan and view.since_scan == judged_on.since_scan


def _stopped(ran: Ran, motion: Motion, senses: RobotSenses, after_s: float, reasons: list[str],
             advice: list[str]) -> None:
    if ran.slices:
        senses.stop(motion.topic, motion.msg_type)
    ran.verdict, ran.ran_s = "stopped", round(after_s, 3)
    ran.reasons = [f"stopped {after_s:.2f} s into the motion" if ran.slices else "refused before it started",
                   *reasons]
    ran.advice = advice
