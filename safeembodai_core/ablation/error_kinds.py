"""What ended an ``error`` trial: a backend outage, a state store that could not write, a failure
another component reported, a crash, or components that could not be built.

The trial loop names the kind in :attr:`~safeembodai_core.models.TrialResult.error_kind`
(``loop/trial.py``): ``backend`` for a :class:`~safeembodai_core.errors.BackendError`, ``store``
for a :class:`~safeembodai_core.errors.StateStoreError`, ``reported`` for any other
:class:`~safeembodai_core.errors.SafeEmbodAIError`, ``crash`` for anything else (a bug; the log says
``trial.crashed``), and ``error_result`` says ``build``. These functions read that field.

Results stored before the field existed have ``error_kind`` None; for them alone the kind is read
off the detail, as earlier versions did: a crash's detail starts with an exception class name
(``"ZeroDivisionError: ..."``), SafeEmbodAI's own messages start with what failed ("llm backend
...", "scripted backend: ...", "state store could not ...", "components could not be built: ...",
an environment's kind).
"""

from __future__ import annotations

import re
from typing import Iterable

from ..models import Outcome, TrialResult

_EXCEPTION_NAME = re.compile(r"^(?=[A-Za-z_])[\w.]*(Error|Exception|Exit|Interrupt|Warning|Failure|error): ")

#: Every kind, in the order reports list them.
KINDS = ("backend", "store", "reported", "build", "crash")


def error_kind(result: TrialResult) -> str | None:
    """The kind of an ``error`` trial (None for any other outcome)."""
    if result.outcome != Outcome.ERROR:
        return None
    if result.error_kind is not None:
        return result.error_kind
    detail = result.detail
    if _EXCEPTION_NAME.match(detail):
        return "crash"
    if detail.startswith("state store could not"):
        return "store"
    if detail.startswith("components could not be built"):
        return "build"
    if "backend" in detail.partition(":")[0]:  # "llm backend 'gpt-4o' ... gave up", "scripted backend: ..."
        return "backend"
    return "reported"


def crashed(result: TrialResult) -> bool:
    """True for a trial ended by an unexpected exception in a component (not an outage)."""
    return error_kind(result) == "crash"


def count_crashed(results: Iterable[TrialResult]) -> int:
    return sum(crashed(r) for r in results)


def store_failed(result: TrialResult) -> bool:
    """True for a trial ended because the state store could not record it (full disk, locked file)."""
    return error_kind(result) == "store"


def all_errored(results: list[TrialResult]) -> str | None:
    """One line saying why a run is a failure when every one of its trials ended ``error``, else None."""
    if not results or any(r.outcome != Outcome.ERROR for r in results):
        return None
    kinds: dict[str, int] = {}
    for result in results:
        kind = error_kind(result) or "reported"
        kinds[kind] = kinds.get(kind, 0) + 1
    counted = ", ".join(f"{kinds[k]} {k}" for k in KINDS if k in kinds)
    return (f"every one of the {len(results)} trials ended in error ({counted}); no metric could be computed. "
            f"First: {results[0].detail or 'no detail'}")
