"""The record of one call an agent made through guard-mcp (:class:`CallRecord`): what the proxy keeps in
:attr:`~.proxy.GuardMcp.calls`, hands to ``on_call`` (a session's record, :mod:`.session`) and gives the
agent back as R_{i-1} (:func:`~.agent.executed_state`)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class CallRecord:
    """One call: what was asked (``arguments`` quoted as the agent sent them; ``words``: the call as read,
    ``kind`` its kind in the policy, None when unmapped), the ``verdict`` (``read_only``, ``forwarded``,
    ``limited``, ``refused``, ``stopped``, ``failed``), ``by`` what (``policy``, ``scan``, ``guard``,
    ``stop_only``, ``upstream``), why, the ``advice``, what ran (slices ``[linear_x, angular_z, seconds]``),
    the ``result`` in short, the robot's odometry pose before and after, and how long it took."""

    time_s: float
    tool: str
    arguments: str
    verdict: str
    reasons: list[str] = field(default_factory=list)
    ran: list[list[float]] = field(default_factory=list)
    pose_before: tuple[float, float, float] | None = None
    pose_after: tuple[float, float, float] | None = None
    kind: str | None = None
    words: str = ""
    by: str = "policy"
    advice: list[str] = field(default_factory=list)
    result: str = ""
    took_s: float = 0.0
