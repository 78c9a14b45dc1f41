"""What :class:`~safeembodai_core.Guard` answers: a plan's verdicts, a held command's, a speed limit."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..models import LLMResponse, Straight, Turn, Verdict
from ..ros.twist import Twist


@dataclass
class GuardReport:
    """The outcome of :meth:`Guard.check`: every verdict, and the parsed signals if they parsed."""

    signals: list[Straight | Turn] = field(default_factory=list)
    verdicts: list[Verdict] = field(default_factory=list)
    response: LLMResponse | None = None
    #: why the reply could not be read (it then has one ``schema`` verdict saying the same); None when it was read
    parse_error: str | None = None

    @property
    def valid(self) -> bool:
        return all(v.valid for v in self.verdicts)

    @property
    def reasons(self) -> list[str]:
        """Each refusal as the trial loop writes it (``Attempt.failures()``): the reading's refusal, or
        ``rule (signal K): reason`` per refused signal."""
        if self.parse_error is not None:
            return [self.parse_error]
        return [v.line() for v in self.verdicts if not v.valid]


@dataclass
class TwistReport(GuardReport):
    """:meth:`Guard.check_twist`'s outcome: the verdicts (rules that judge the held motion exactly,
    then the others on the arc's pieces, ``signals``), the longest time the command can be held
    safely (``safe_duration_s``: the asked duration when it passes; 0 when nothing of it does), and
    the **time before collision** (``collision_time_s``: when the swept body would first touch
    something within the hold, None when it touches nothing; ``contact`` says whether a ``return``
    or ``unseen`` space), as Nav2's collision monitor computes it for its approach polygon.
    ``obstacle_time_s`` is the first touch of a return alone (Nav2's quantity: it sees only
    returns), ``unseen_time_s`` the first touch of space the scan did not see."""

    twist: Twist | None = None
    duration_s: float = 0.0
    safe_duration_s: float = 0.0
    collision_time_s: float | None = None
    contact: str | None = None
    obstacle_time_s: float | None = None
    unseen_time_s: float | None = None

    @property
    def reasons(self) -> list[str]:
        """The refusal said for the command as a whole first, then each rule's, as in :meth:`GuardReport.reasons`."""
        lines = GuardReport.reasons.fget(self)  # type: ignore[attr-defined]
        if not lines or self.twist is None:
            return lines
        t = self.twist
        sideways = f", linear.y {t.linear_y:g} m/s" if t.linear_y else ""
        pieces = f" (the arc judged as {len(self.signals)} pieces)" if self.signals else ""
        head = (f"twist linear.x {t.linear_x:g} m/s{sideways}, angular.z {t.angular_z:g} rad/s for "
                f"{self.duration_s:g} s: refused; at most {self.safe_duration_s:.2f} s is safe{pieces}")
        return [head, *lines]


@dataclass
class LimitReport:
    """:meth:`Guard.limit_twist`'s outcome: the command to send (``twist``: the asked one scaled by
    ``factor`` in [0, 1], along the same path), why it was limited (``reasons``, empty when it was
    not), the asked command (``requested``) and its judgement over the horizon (``report``)."""

    twist: Twist
    factor: float
    requested: Twist
    horizon_s: float
    report: TwistReport
    reasons: list[str] = field(default_factory=list)
    #: the slow-down zones that held a return, by name
    zones: list[str] = field(default_factory=list)

    @property
    def limited(self) -> bool:
        return self.factor < 1.0

    @property
    def stopped(self) -> bool:
        return self.factor == 0.0

    @property
    def collision_time_s(self) -> float | None:
        return self.report.collision_time_s


__all__ = ["GuardReport", "LimitReport", "TwistReport"]
