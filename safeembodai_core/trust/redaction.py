"""Redaction: credentials masked in any text before it is logged, stored or shown.

Any mapping key that names a credential (``api_key``, ``authorization``, ``secret``,
``password``, ``token`` but not token *counts*) is masked, and so is any value that looks like a
bearer key (``sk-...``) or equals a value given to :func:`register_secret`. Logging
(:mod:`safeembodai_core.logs`), storing and showing text (:mod:`safeembodai_core.trust.text`)
and quoting it to an LLM (:mod:`safeembodai_core.trust.quoting`) all go through :func:`redact`.
What is kept on disk as it came (the response cache) asks :func:`secret_encoding` first: it finds
a registered secret in the encodings a reflecting server is known to use, which :func:`redact`
does not undo.
"""

from __future__ import annotations

import base64
import re
from typing import Any, Iterable
from urllib.parse import unquote

#: Characters that can reorder, hide or break a line a reader sees and that JSON leaves as they
#: are: DEL and C1 controls, line/paragraph separators, bidi controls, lone surrogates (a regex
#: character-class body; :mod:`.text_safety` adds the C0 controls for terminals).
UNSAFE_BEYOND_JSON = ("\x7f-\x9f\u00ad\u034f\u061c\u180e\u200b-\u200f\u2028\u2029\u202a-\u202e\u2060-\u2064"
                      "\u2066-\u2069\ufeff\ufff9-\ufffb\ud800-\udfff\U000e0000-\U000e007f\U000e0100-\U000e01ef")

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


#: Encoded forms are looked for only for secrets this long: a shorter one's base64 or hex could turn
#: up in ordinary text by chance.
MIN_ENCODED_SECRET_CHARS = 8


def _base64_cores(secret: bytes, encode: Any) -> list[str]:
    """The characters of ``secret``'s base64 that depend on its bytes alone, for each of the three
    alignments it can have in a longer stream (0, 1 or 2 bytes before it)."""
    cores = []
    for before in range(3):
        encoded = encode(b"\0" * before + secret).decode("ascii")
        start, end = -(-8 * before // 6), 8 * (before + len(secret)) // 6
        cores.append(encoded[start:end])
    return cores


def _encodings(secret: str) -> list[tuple[str, list[str]]]:
    raw = secret.encode("utf-8")
    return [("reversed", [secret[::-1]]), ("hex", [raw.hex()]),
            ("base64", _base64_cores(raw, base64.b64encode)),
            ("url-safe base64", _base64_cores(raw, base64.urlsafe_b64encode))]


_ESCAPE = re.compile(r"\\(u[0-9a-fA-F]{4}|[\\/\"bfnrt])")
_ESCAPED = {"\\": "\\", "/": "/", '"': '"', "b": "\b", "f": "\f", "n": "\n", "r": "\r", "t": "\t"}


def _json_layers(text: str, most: int = 3) -> list[str]:
    """``text`` and the text its JSON escapes stand for, again for a JSON string inside a JSON string
    (a stored reply holds the answer's JSON as text): up to ``most`` layers down."""
    layers = [text]
    while len(layers) <= most and "\\" in layers[-1]:
        down = _ESCAPE.sub(lambda m: chr(int(m.group(1)[1:], 16)) if len(m.group(1)) == 5 else _ESCAPED[m.group(1)],
                           layers[-1])
        if down == layers[-1]:
            break
        layers.append(down)
    return layers


def secret_encoding(text: str) -> str | None:
    """How ``text`` holds a registered secret (:func:`register_secret`), or None: ``literal``,
    ``split by invisible characters``, ``URL-encoded``, ``reversed``, ``hex``, ``base64`` or
    ``url-safe base64`` (each alignment of the secret in the stream). JSON escapes are read first,
    layer by layer (``text`` may be a stored reply's JSON). The answer never holds the secret."""
    if not _secrets:
        return None
    invisible = re.compile(f"[\\x00-\\x1f{UNSAFE_BEYOND_JSON}]")
    for layer in _json_layers(text):
        joined = invisible.sub("", layer)
        unquoted, lowered = unquote(joined), joined.lower()
        for secret in sorted(_secrets, key=len, reverse=True):
            if secret in layer:
                return "literal"
            if secret in joined:
                return "split by invisible characters"
            if secret in unquoted:
                return "URL-encoded"
            if len(secret) < MIN_ENCODED_SECRET_CHARS:
                continue
            for how, forms in _encodings(secret):
                if any(form and form in (lowered if how == "hex" else joined) for form in forms):
                    return how
    return None
