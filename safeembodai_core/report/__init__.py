"""Reports of a finished run: metrics as CSV/JSON and a Markdown report."""

from .writer import write_report

__all__ = ["write_report"]
