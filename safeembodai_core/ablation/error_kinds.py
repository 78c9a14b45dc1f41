"""What ended an ``error`` trial: a backend outage, a state store that could not write, or a crash.

The trial loop ends a trial ``error`` both when a :class:`~safeembodai_core.errors.SafeEmbodAIError`
is raised (a backend that gave up, a failing plugin or store: the message itself is the detail)
and when a component raises anything else (a bug: the detail is ``"<ExceptionType>: <message>"``
and the log says ``trial.crashed``). :class:`~safeembodai_core.models.TrialResult` has no field
for the difference, so it is read off the detail: a crash's detail starts with an exception
class name. SafeEmbodAI's own messages start with what failed ("llm backend ...", "state store
...", "plugin ...", an environment's kind), never with such a name. A store that could not
record the trial says "state store could not ..." (``loop/trial.py``).

A field of ``TrialResult`` naming the kind would be sturdier than reading text; until it
exists, these functions are the one place that reads it.
"""

from __future__ import annotations

import re
from typing import Iterable

from ..models import Outcome, TrialResult

_EXCEPTION_NAME = re.compile(r"^(?=[A-Za-z_])[\w.]*(Error|Exception|Exit|Interrupt|Warning|Failure|error): ")


def crashed(result: TrialResult) -> bool:
    """True for a trial ended by an unexpected exception in a component (not an outage)."""
    return result.outcome == Outcome.ERROR and bool(_EXCEPTION_NAME.match(result.detail))


def count_crashed(results: Iterable[TrialResult]) -> int:
    return sum(crashed(r) for r in results)


def store_failed(result: TrialResult) -> bool:
    """True for a trial ended because the state store could not record it (full disk, locked file)."""
    return result.outcome == Outcome.ERROR and result.detail.startswith("state store could not")
