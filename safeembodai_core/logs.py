"""Logging: structlog to stderr, with secrets redacted before anything is written.

Any event key that names a credential (``api_key``, ``authorization``, ``secret``, ``password``,
``token`` but not token *counts*) is masked, and so is any value that looks like a bearer key
(``sk-...``). Backends must still never log credentials; this is the safety net.
"""

from __future__ import annotations

import logging
import re
import sys
from typing import Any, Iterable

import structlog

_SECRET_KEY = re.compile(r"(api[_-]?key|authorization|secret|password|passwd|bearer|^token$|access[_-]?token)", re.I)
_SECRET_VALUE = re.compile(r"\b(sk|rk|pk)-[A-Za-z0-9_\-]{8,}|\bBearer\s+[A-Za-z0-9._\-]{8,}")
MASK = "***"
_MIN_SECRET_CHARS = 4
_secrets: set[str] = set()


def register_secret(value: str | None) -> None:
    """Redact ``value`` (a configured credential) from every text that :func:`redact` sees.

    Backends call this with the key they were configured with, so a server that reflects the key
    into an answer cannot get it stored, logged or displayed. Values shorter than 4 characters are
    ignored (masking them would garble ordinary text).
    """
    if value and len(value) >= _MIN_SECRET_CHARS:
        _secrets.add(value)


_JSON_ESCAPE = re.compile(r"\\u([0-9a-fA-F]{4})|\\(/)")


def _unescape_json(text: str) -> str:
    return _JSON_ESCAPE.sub(lambda m: m.group(2) or chr(int(m.group(1), 16)), text)


def mask_values(text: str, values: Iterable[str]) -> str:
    """``text`` with every one of ``values`` (empty ones skipped) replaced by the mask, longest first."""
    for value in sorted((v for v in values if v), key=len, reverse=True):
        if value in text:
            text = text.replace(value, MASK)
    return text


def _mask_registered(text: str) -> str:
    if "\\" in text and not any(secret in text for secret in _secrets):
        # a secret written with JSON escapes ("sk\u002d...") in raw answer text: the decoded
        # view is what a reader recovers, so when it holds a secret the decoded text is kept
        decoded = _unescape_json(text)
        if any(secret in decoded for secret in _secrets):
            text = decoded
    return mask_values(text, _secrets)


def redact(value: Any) -> Any:
    """Mask anything that looks like a credential inside ``value`` (recursively): every value
    given to :func:`register_secret`, and anything shaped like a bearer key."""
    if isinstance(value, str):
        return _SECRET_VALUE.sub(MASK, _mask_registered(value) if _secrets else value)
    if isinstance(value, dict):
        return {k: (MASK if isinstance(k, str) and _SECRET_KEY.search(k) else redact(v)) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(redact(v) for v in value)
    return value


def _redact_processor(logger: Any, method: str, event: dict[str, Any]) -> dict[str, Any]:
    return redact(event)


def _visible_controls(value: Any) -> Any:
    if isinstance(value, str):
        from .text_safety import terminal_text  # imports this module: resolved at call time

        return terminal_text(value, keep_layout=True)
    if isinstance(value, dict):
        return {k: _visible_controls(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_visible_controls(v) for v in value)
    return value


def _terminal_safe_processor(logger: Any, method: str, event: dict[str, Any]) -> dict[str, Any]:
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
        logger_factory=structlog.PrintLoggerFactory(file=_CurrentStderr()),
        cache_logger_on_first_use=False,
    )
