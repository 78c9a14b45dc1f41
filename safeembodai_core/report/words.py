"""A trial told in words: counts with their noun, and what ended a trial.

Shared by the commands that print trials (``run``, ``ablate``) and by the ``sqlite`` plugin's
``show``; in the core, not in a command's module, so a plugin never imports the CLI. Light to
import (the CLI's modules import it at start-up): the models are imported when a trial is told.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from ..models import StepRecord, TrialResult


def plural(count: int, noun: str) -> str:
    """``1 step``, ``2 steps``."""
    return f"{count} {noun}{'' if count == 1 else 's'}"


def trial_ending(result: TrialResult, steps: list[StepRecord]) -> str:
    """What ended the trial, in words ("" when its outcome says it all).

    The result's own detail when it has one; for an interrupted trial without one, the collision
    on record in its last steps: an executed command's result, or a collision while the robot
    waited (reported in the next observation's ground truth).
    """
    from ..models import Outcome

    if result.detail:
        return result.detail
    if result.outcome != Outcome.INTERRUPTED:
        return ""
    for record in reversed(steps):
        for item in reversed(record.executed):
            if item.result.collided:
                what = item.result.detail or (f"hit {item.result.hit}" if item.result.hit else "collided")
                return (f"{item.result.collision or 'unattributed'} collision at step {record.step}: "
                        f"{item.signal.describe()} -> {what}")
        truth = record.truth
        if truth.collision is not None:
            when = truth.collision_detail or "while the robot waited"
            return f"{truth.collision} collision before step {record.step}: {when}"
    return "the environment ended it; no collision on record"
