"""Redaction: credentials masked in any text before it is logged, stored or shown.

Any mapping key that names a credential (``api_key``, ``authorization``, ``secret``,
``password``, ``token`` but not token *counts*) is masked, and so is any value that looks like a
bearer key (``sk-...``) or equals a value given to :func:`register_secret`. Logging
(:mod:`safeembodai_core.logs`), storing and showing text (:mod:`safeembodai_core.text_safety`)
and quoting it to an LLM (:mod:`safeembodai_core.quoting`) all go through :func:`redact`.
"""

from __future__ import annotations

import re
from typing import Any, Iterable

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
