"""Rules that judge a held velocity exactly, not as the contract's signals.

A velocity command held for a while (``geometry_msgs/Twist``) is an arc. Rules that know only the
contract's signals judge it cut into short straights and turns
(:func:`~safeembodai_core.ros.arc_signals`), which cannot say *when* the body would touch
something and cannot judge a sideways (holonomic) command at all. A :class:`MotionValidator` also
judges the :class:`~safeembodai_core.geometry.Motion` itself and says the time of first contact:
:meth:`Guard.check_twist <safeembodai_core.Guard.check_twist>` and
:meth:`Guard.limit_twist <safeembodai_core.Guard.limit_twist>` use it for the time before collision
and the speed limit, as Nav2's collision monitor does with its approach polygon.
"""

from __future__ import annotations

from abc import abstractmethod
from dataclasses import dataclass
from typing import Literal

from ..geometry import Motion
from ..models import Verdict
from ..validation.context import ValidationContext, Validator


@dataclass(frozen=True)
class MotionVerdict:
    """A rule's judgement of a held motion: the verdict, and the first moment (seconds from the
    start of the hold) at which the body would touch something -- ``contact_s`` None when nothing
    within the hold. ``contact`` says what: a ``return`` of the scan, or ``unseen`` space the scan
    cannot vouch for (no reading, outside the field of view, beyond its range, behind a return);
    ``return_s`` and ``unseen_s`` are the first touch of each (None: none within the hold)."""

    verdict: Verdict
    contact_s: float | None = None
    contact: Literal["return", "unseen"] | None = None
    return_s: float | None = None
    unseen_s: float | None = None


class MotionValidator(Validator):
    """A validator that also judges a held motion exactly (module docstring)."""

    @abstractmethod
    def validate_motion(self, motion: Motion, context: ValidationContext) -> MotionVerdict:
        """Judge ``motion`` (a velocity held from the planned pose in ``context``); say the first contact."""


__all__ = ["MotionValidator", "MotionVerdict"]
