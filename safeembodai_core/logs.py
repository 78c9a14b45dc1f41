"""Logging: structlog to stderr, with secrets redacted before anything is written.

Any event key that names a credential (``api_key``, ``authorization``, ``secret``, ``password``,
``token`` but not token *counts*) is masked, and so is any value that looks like a bearer key
(``sk-...``): :func:`~safeembodai_core.trust.redaction.redact`, re-exported here with
:func:`register_secret`, :func:`mask_values` and :data:`MASK`. Backends must still never log
credentials; this is the safety net.
"""

from __future__ import annotations

import logging
import sys
from typing import Any, TextIO, cast

import structlog
from structlog.typing import EventDict, WrappedLogger

from .trust.redaction import MASK, mask_values, redact, register_secret
from .trust.text import terminal_text

__all__ = ["MASK", "configure_logging", "get_logger", "mask_values", "redact", "register_secret"]


def _redact_processor(logger: WrappedLogger, method: str, event: EventDict) -> EventDict:
    return redact(event)


def _visible_controls(value: Any) -> Any:
    if isinstance(value, str):
        return terminal_text(value, keep_layout=True)
    if isinstance(value, dict):
        return {k: _visible_controls(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_visible_controls(v) for v in value)
    return value


def _terminal_safe_processor(logger: WrappedLogger, method: str, event: EventDict) -> EventDict:
    """Logged values can quote an LLM's answer: ESC, NUL and bidi controls are shown, not sent."""
    return _visible_controls(event)


class _CurrentStderr:
    """Whatever ``sys.stderr`` is at write time (tests and embedding apps swap it)."""

    def write(self, text: str) -> int:
        return sys.stderr.write(text)

    def flush(self) -> None:
        sys.stderr.flush()


def get_logger(name: str) -> Any:
    """A structlog logger; if nobody configured structlog, first route it to stderr at WARNING.

    structlog's own default prints every level to stdout, which would leak debug chatter into a
    library user's output (or a CLI's tables). An application that configures structlog itself
    keeps its configuration.
    """
    if not structlog.is_configured():
        configure_logging("warning")
    return structlog.get_logger(name)


def configure_logging(level: str = "warning", json_output: bool = False) -> None:
    """Send structlog events at ``level`` or above to stderr (plain text, or JSON lines)."""
    numeric = getattr(logging, level.upper(), logging.WARNING)
    renderer = (structlog.processors.JSONRenderer() if json_output
                else structlog.dev.ConsoleRenderer(colors=False, exception_formatter=structlog.dev.plain_traceback))
    structlog.configure(
        processors=[
            structlog.contextvars.merge_contextvars,
            structlog.processors.add_log_level,
            structlog.processors.TimeStamper(fmt="iso"),
            structlog.processors.format_exc_info,  # tracebacks become text *before* redaction, without locals
            _redact_processor,
            _terminal_safe_processor,
            renderer,
        ],
        wrapper_class=structlog.make_filtering_bound_logger(numeric),
        # structlog only writes and flushes its file: the stand-in needs no more of TextIO
        logger_factory=structlog.PrintLoggerFactory(file=cast(TextIO, _CurrentStderr())),
        cache_logger_on_first_use=False,
    )
