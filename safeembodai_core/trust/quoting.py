"""Quoting untrusted text before it goes in front of an LLM (or a person) again.

Text an attacker or the LLM wrote -- a human instruction, a plan, a key or tag of a refused
answer -- is only ever shown as a JSON string literal: quotes, backslashes and newlines are
escaped, so it cannot close its quotes and pose as a new section of the prompt (``Role: ...``,
``SYSTEM: ...``). JSON leaves a few characters unescaped that can still break a line or
reorder what a reader sees; they are escaped here too: C1 controls and DEL, the Unicode line and
paragraph separators, bidirectional-text controls ("Trojan Source"), lone surrogates (which
are not valid Unicode and cannot even be encoded as UTF-8) and invisible characters that can
carry text a reader never sees: zero-width spaces and joiners, word joiners and invisible
operators, the byte-order mark, the soft hyphen, Unicode tag characters (U+E0000-U+E007F, which
can spell a whole hidden instruction) and the supplementary variation selectors. Ordinary text,
accents and emoji included, is left as it is (the emoji variation selectors U+FE00-U+FE0F too,
and a zero-width joiner inside an emoji sequence is shown escaped).

The prompt templates' ``quoted`` filter and the answer parser's refusal reasons both use
:func:`quote_untrusted`, so every LLM-facing quotation follows the same rule.
"""

from __future__ import annotations

import json
import re
from typing import Any

from .redaction import UNSAFE_BEYOND_JSON, redact  # the one set of invisible characters: defined there

CLIPPED = "[...]"
_STILL_UNSAFE = re.compile(f"[{UNSAFE_BEYOND_JSON}]")


def _escape(match: re.Match[str]) -> str:
    code = ord(match.group())
    if code > 0xFFFF:  # a JSON escape of a character beyond the BMP is its surrogate pair
        code -= 0x10000
        return f"\\u{0xD800 + (code >> 10):04x}\\u{0xDC00 + (code & 0x3FF):04x}"
    return f"\\u{code:04x}"


def quote_untrusted(value: Any, max_chars: int | None = None) -> str:
    """``value`` (made a string) as a JSON string literal that cannot break out of its quotes.

    Configured secrets and bearer-shaped keys are masked first (:func:`~safeembodai_core.trust.redaction.redact`).
    With ``max_chars`` only the first ``max_chars`` characters are quoted and ``[...]`` follows
    the closing quote, so what is inside the quotes is always exactly what was written.
    """
    text = redact(str(value))  # before clipping: a cut must never leave part of a secret readable
    clipped = max_chars is not None and len(text) > max_chars
    if clipped:
        assert max_chars is not None  # clipped implies a limit
        text = text[: max(0, max_chars)]
    literal = _STILL_UNSAFE.sub(_escape, json.dumps(text, ensure_ascii=False))
    return literal + CLIPPED if clipped else literal
