"""Control characters are one set, written once (``safeembodai_core.trust.redaction.UNSAFE_BEYOND_JSON`` and
the patterns ``safeembodai_core.trust.text`` builds on it): a new hand-written class of control characters
fails here."""

from __future__ import annotations

import re
from pathlib import Path

from safeembodai_core.trust.text import CONTROL, CONTROL_OR_LAYOUT

REPO = Path(__file__).resolve().parents[2]
#: a regex class spelling out, by hand, what only a display needs: C1 controls, separators, bidi overrides
#: (JSON's own rule for raw C0 inside a string, in the strict JSON reader and the grammar's pattern, is JSON's)
HAND_WRITTEN = re.compile(r"\\x7f-\\x9f|\\u202a-\\u202e|\\u2028")
HOMES = {REPO / "safeembodai_core" / "trust" / "redaction.py", REPO / "safeembodai_core" / "trust" / "text.py"}


def test_no_module_writes_its_own_control_character_class():
    found = [f"{path.relative_to(REPO)}:{number}" for folder in ("safeembodai_core", "plugins")
             for path in sorted((REPO / folder).rglob("*.py")) if path not in HOMES
             for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
             if HAND_WRITTEN.search(line)]
    assert not found, f"use safeembodai_core.trust.text.CONTROL or CONTROL_OR_LAYOUT: {found}"


def test_the_one_set_covers_what_the_copies_covered():
    """What the litellm plugin's own class held (C0, C1, DEL, separators, zero-width, bidi) is in the set."""
    for char in ["\x00", "\x1b", "\x7f", "\x85", "\u2028", "\u2029", "\u200b", "\u200f", "\u202e", "\u2066"]:
        assert CONTROL_OR_LAYOUT.search(char), repr(char)
    assert CONTROL_OR_LAYOUT.search("\n") and not CONTROL.search("\n") and not CONTROL.search("\t")
    assert not CONTROL_OR_LAYOUT.search("plain text, é and 日本")
