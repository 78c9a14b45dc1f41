"""A plan of straights and turns as a ``publish_for_durations`` call, and a refusal of it as data.

The pilot plans in the paper's signals (``straight`` d mm, ``turn`` a degrees). A base drives
velocities, so each signal becomes one ``geometry_msgs/msg/Twist`` held for the time it takes at the
room's own speeds (:class:`Speeds`: a straight of d mm at v mm/s is held d / v seconds; a turn of a
degrees at w deg/s, a / w), and the plan ends with a stop. The stop is held :data:`STOP_S` rather
than 0 s: ros-mcp 3.1.2 publishes a message of duration 0 once and then waits up to a second for a
status reply (``tools/topics.py``), a second the robot would stand for nothing. Messages are
streamed at ``rate_hz`` (a base holds a message only for its ``cmd_vel_timeout``).

A refusal that comes back (guard-mcp's tool error: ``reasons``, ``advice`` and the numbers in
``safe``) is read into the core's :class:`~safeembodai_core.models.Verdict`, which the step's attempt
hands on as a :class:`~safeembodai_core.models.Refusal`: the refused message is the plan's signal of that index,
and ``at_most_mm`` / ``at_most_deg`` say how much of it is safe -- what Algorithm 1's retry hands a
pilot, which reads the numbers, never the words.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Sequence

from ..models import Advice, ControlSignal, Straight, Verdict

TWIST = "geometry_msgs/msg/Twist"
#: How long the closing stop is streamed (seconds): see the module docstring.
STOP_S = 0.1
#: The rule name a refusal from the MCP server is recorded under.
RULE = "guard_mcp"


@dataclass(frozen=True)
class Speeds:
    """The speeds a plan is driven at: the room's straight-line speed and turn rate."""

    linear_mm_s: float = 200.0
    turn_deg_s: float = 60.0

    def __post_init__(self) -> None:
        for name in ("linear_mm_s", "turn_deg_s"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name} must be a positive number, got {value!r}")


def twist(linear_m_s: float = 0.0, angular_rad_s: float = 0.0) -> dict[str, dict[str, float]]:
    """A full ``geometry_msgs/msg/Twist`` (every field: a guard refuses a partial message)."""
    return {"linear": {"x": float(linear_m_s), "y": 0.0, "z": 0.0},
            "angular": {"x": 0.0, "y": 0.0, "z": float(angular_rad_s)}}


def held(signal: ControlSignal, speeds: Speeds) -> tuple[dict[str, Any], float]:
    """One signal as the twist that drives it and how long it is held."""
    if isinstance(signal, Straight):
        sign = 1.0 if signal.direction == "forward" else -1.0
        return twist(sign * speeds.linear_mm_s / 1000.0), signal.distance / speeds.linear_mm_s
    sign = 1.0 if signal.direction == "left" else -1.0
    return twist(0.0, sign * math.radians(speeds.turn_deg_s)), signal.angle / speeds.turn_deg_s


def motion_arguments(plan: Sequence[ControlSignal], speeds: Speeds, *, topic: str = "/cmd_vel",
                     rate_hz: float = 10.0) -> dict[str, Any]:
    """``publish_for_durations``'s arguments for ``plan``: one message per signal, then a stop."""
    messages, durations = [], []
    for signal in plan:
        message, seconds = held(signal, speeds)
        messages.append(message)
        durations.append(round(seconds, 3))
    messages.append(twist())
    durations.append(STOP_S)
    return {"topic": topic, "msg_type": TWIST, "messages": messages, "durations": durations, "rate_hz": rate_hz}


def runs_s(arguments: dict[str, Any]) -> float:
    """How long a ``publish_for_durations`` call asks to run (seconds)."""
    return float(sum(arguments.get("durations", ())))


def _number(value: Any) -> float | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        return None
    return float(value)


def refusal_body(content: Any) -> dict[str, Any] | None:
    """The refusal a tool error's content carries (guard-mcp's ``{"refused": true, ...}``), else None."""
    return content if isinstance(content, dict) and content.get("refused") is True else None


def _inner(body: dict[str, Any]) -> dict[str, Any]:
    """What a motion stopped mid-way keeps under ``guard``."""
    inner = body.get("guard")
    return inner if isinstance(inner, dict) else {}


def reasons_of(body: dict[str, Any]) -> list[str]:
    """The refusal's reasons and advice in words (a motion stopped mid-way keeps them under ``guard``)."""
    inner = _inner(body)
    words = [*body.get("reasons", []), *inner.get("reasons", []), *body.get("advice", []), *inner.get("advice", [])]
    return [str(word)[:400] for word in words if isinstance(word, str)][:12]


def verdict(body: dict[str, Any], plan: Sequence[ControlSignal]) -> Verdict:
    """``body`` (a refusal, :func:`refusal_body`) of ``plan`` as the verdict of a rule: the attempt that sent
    the plan then hands it on as a :class:`~safeembodai_core.models.Refusal` (``Attempt.refusals``)."""
    safe = body.get("safe") or _inner(body).get("safe") or {}
    safe = safe if isinstance(safe, dict) else {}
    index = safe.get("message")
    index = index if isinstance(index, int) and not isinstance(index, bool) and 0 <= index < len(plan) else None
    advice = None
    if index is not None:
        if isinstance(plan[index], Straight):
            advice = Advice(safe_mm=_number(safe.get("at_most_mm")))
        else:
            advice = Advice(safe_deg=_number(safe.get("at_most_deg")))
    reason = "; ".join(reasons_of(body)) or "refused by the MCP server"
    return Verdict(rule=RULE, valid=False, reason=reason[:2000], signal_index=index, advice=advice)


def stop_only(body: dict[str, Any]) -> bool:
    """The server answers nothing but stops now (guard-mcp's failure threshold reached)."""
    return body.get("stop_only") is True
