"""Reports of a finished run: metrics as CSV/JSON and a Markdown report.

``write_report`` is imported on first use (PEP 562), so a light module of this package (``words``: how a
trial's ending is said, which ``safeembodai run`` and ``show`` need at start-up) does not bring the writer's
libraries with it.
"""

from typing import TYPE_CHECKING, Any

__all__ = ["write_report"]


def __getattr__(name: str) -> Any:
    if name == "write_report":
        from .writer import write_report

        return write_report
    raise AttributeError(f"module 'safeembodai_core.report' has no attribute {name!r}")


if TYPE_CHECKING:  # pragma: no cover
    from .writer import write_report  # noqa: F401
