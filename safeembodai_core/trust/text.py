"""Untrusted text made safe to store and to show an operator.

An LLM's answer, an attacker's payload and whatever a backend reports end up in the state
store and on the operator's terminal. Two rules, one module:

* **stored** -- :func:`storable` returns a copy of a record (a pydantic model, at any depth) in
  which every string is redacted (:func:`~safeembodai_core.trust.redaction.redact`: registered secrets and
  bearer-shaped keys become ``***``) and encodable (lone surrogates, the only code points UTF-8
  cannot encode, become U+FFFD; NUL and other controls are kept, JSON and SQLite hold them), and
  every integer fits SQLite's INTEGER (clamped to +-(2**63-1)). The trial loop applies it before a
  record reaches any store, the built-in stores apply it again for library callers: storing can
  then fail only for the store's own reasons (disk, locks), never because of what an answer held.
* **shown** -- :func:`terminal_text` makes control characters visible (``\\x1b`` for ESC,
  ``\\x00`` for NUL, ``\\u202e`` for a bidi override, ``\\u200b`` for a zero-width space,
  ``\\U000e0041`` for a Unicode tag character), so an answer cannot clear the screen, write
  the clipboard (OSC 52), hide text from the operator or reorder a line; :func:`terminal_markup` also escapes rich
  markup for text placed inside a markup string. ``run`` and ``show`` print LLM-written text only
  through them.

LLM-facing quotation (text shown to the model again) is :mod:`safeembodai_core.trust.quoting`.
"""

from __future__ import annotations

import math
import re
from typing import Any, TypeVar

from pydantic import BaseModel

from .redaction import redact
from .quoting import UNSAFE_BEYOND_JSON

SQLITE_MAX_INT = 2**63 - 1
REPLACEMENT = "\ufffd"
IDENTITY_FIELDS = frozenset({"trial_id", "spec"})  # keys the store files a record under: never rewritten

_SURROGATE = re.compile("[\ud800-\udfff]")
# C0 and C1 controls, DEL, line/paragraph separators, bidi controls, lone surrogates: the project's one set of
# characters a person must not be shown raw (UNSAFE_BEYOND_JSON is what JSON's own escapes leave of it)
_INVISIBLE = "\x00-\x08\x0b-\x1f" + UNSAFE_BEYOND_JSON
#: one control character (tab and newline, which lay text out, are not)
CONTROL = re.compile(f"[{_INVISIBLE}]")
#: one control character, tab and newline included: what a one-line message must not hold
CONTROL_OR_LAYOUT = re.compile(f"[{_INVISIBLE}\t\n]")

Record = TypeVar("Record", bound=BaseModel)


def storable_text(text: str) -> str:
    """``text`` redacted and encodable as UTF-8 (lone surrogates replaced by U+FFFD)."""
    return redact(_SURROGATE.sub(REPLACEMENT, text))


def storable_int(value: int) -> int:
    """``value`` clamped to what SQLite's 64-bit INTEGER holds."""
    return max(-SQLITE_MAX_INT, min(SQLITE_MAX_INT, value))


def finite_or_zero(value: float) -> float:
    """``value`` if it is a finite number, else 0.0 (a NaN or infinite measurement is no measurement)."""
    return value if math.isfinite(value) else 0.0


def storable(record: Record) -> Record:
    """A copy of ``record`` that any store can write (see the module docstring).

    Its identity fields (``trial_id``, ``spec``) are left alone so it is filed where it belongs.
    Parts that need no change are shared with ``record``, not copied.
    """
    return _clean_model(record, skip=IDENTITY_FIELDS)


def _clean(value: Any) -> Any:
    """``value`` cleaned; the very same object when nothing in it needed a change."""
    if isinstance(value, str):
        cleaned = storable_text(value)
        return value if cleaned == value else cleaned
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return storable_int(value)
    if isinstance(value, BaseModel):
        return _clean_model(value)
    if isinstance(value, (list, tuple)):
        items = [_clean(item) for item in value]
        return value if all(a is b for a, b in zip(items, value)) else type(value)(items)
    if isinstance(value, dict):
        pairs = [(_clean(k), _clean(v)) for k, v in value.items()]
        same = all(a is k and b is v for (a, b), (k, v) in zip(pairs, value.items()))
        return value if same else dict(pairs)
    return value


def _clean_model(model: Record, skip: frozenset[str] = frozenset()) -> Record:
    changed = {}
    for name in type(model).model_fields:
        if name in skip:
            continue
        old = getattr(model, name)
        new = _clean(old)
        if new is not old:
            changed[name] = new
    return model.model_copy(update=changed) if changed else model


_NAMED = {"\n": "\\n", "\t": "\\t", "\r": "\\r"}


def _visible(match: re.Match[str]) -> str:
    char = match.group()
    if char in _NAMED:
        return _NAMED[char]
    code = ord(char)
    if code > 0xFFFF:
        return f"\\U{code:08x}"
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}"


def terminal_text(text: str, *, keep_layout: bool = False) -> str:
    """``text`` (redacted) with every control character shown as an escape, for a terminal.

    Newlines and tabs are escaped too (a plan cannot pose as another line of the report) unless
    ``keep_layout`` says the text is laid out in lines on purpose.
    """
    pattern = CONTROL if keep_layout else CONTROL_OR_LAYOUT
    return pattern.sub(_visible, redact(str(text)))


def terminal_markup(text: str, *, keep_layout: bool = False) -> str:
    """:func:`terminal_text` with rich markup escaped, for text placed inside a markup string."""
    from rich.markup import escape

    return escape(terminal_text(text, keep_layout=keep_layout))


def one_line(text: str) -> str:
    """``text`` on one line, runs of whitespace made one space (details, error messages)."""
    return " ".join(str(text).split())


_MARKDOWN_PUNCTUATION = re.compile(r"""([!"#$%&'()*+,\-./:;<=>?@\[\\\]^_`{|}~])""")


def markdown_literal(text: str) -> str:
    """``text`` (redacted) as inert Markdown: it renders as the very characters it holds, on one line.

    Control, invisible and layout characters are shown as escapes first (:func:`terminal_text`:
    ``\\u200b``, ``\\U000e0041``, ``\\n``), then every ASCII punctuation character is
    backslash-escaped (CommonMark lets any of them be): no image, link, autolink, raw HTML,
    emphasis, code span, table cell or math an LLM or an attacker wrote survives, so a refused
    ``![x](http://evil/x.png)`` is shown, never loaded. For text placed in a Markdown document
    such as Inspect's transcript.
    """
    return _MARKDOWN_PUNCTUATION.sub(r"\\\1", terminal_text(text))


#: What can make Markdown text more than text: links and images (``[ ] !``), HTML and autolinks (``< >``),
#: entities (``&``), code (`````), emphasis (``* _`` at a word's edge, ``~``), math (``$``), table cells (``|``),
#: headings and lists at a line's start (``# + -``), and the escape itself (``\``).
_MARKDOWN_ACTIVE = re.compile(r"([\\`*\[\]<>!|~&$#])")


def markdown_cell(text: Any, most: int = 400) -> str:
    """``text`` from data (a scenario's names, a store's rule or attack kinds) as inert Markdown in a
    table cell, heading or paragraph of report.md: one line, control and invisible characters shown as
    escapes (:func:`terminal_text`), every character that could make a link, an image, HTML, code, a
    table cell or a heading backslash-escaped, clipped visibly at ``most`` characters. Names stay
    readable (``no_attack`` is left as it is: an underscore inside a word is no emphasis)."""
    line = one_line(terminal_text(str(text)))
    if len(line) > most:
        line = line[:most] + "…"
    return _MARKDOWN_ACTIVE.sub(r"\\\1", line)


def markdown_code(text: Any, most: int = 400) -> str:
    """``text`` for a Markdown code span in a table cell: one line, shown as terminal text, backticks
    made ``'`` (no way out of the span) and ``|`` escaped (GFM splits cells on it even in code)."""
    line = one_line(terminal_text(str(text))).replace("`", "'").replace("|", "\\|")
    return line if len(line) <= most else line[:most] + "…"


#: What a spreadsheet reads as the start of a formula (OWASP's CSV injection list; a tab or a carriage
#: return, the list's other two, is shown as an escape by :func:`terminal_text` first).
_FORMULA_START = ("=", "+", "-", "@")


def csv_cell(value: Any) -> Any:
    """``value`` as a CSV cell a spreadsheet shows as it is: text shown as :func:`terminal_text` and, when
    it starts like a formula (``= + - @``), behind a ``'``; numbers are
    left alone (a negative difference stays a number), non-finite ones left empty."""
    if isinstance(value, float) and not math.isfinite(value):
        return ""
    if not isinstance(value, str):
        return value
    text = terminal_text(value)
    return "'" + text if text.startswith(_FORMULA_START) else text


def json_ready(value: Any) -> Any:
    """``value`` with every non-finite float made None, so ``json.dumps(..., allow_nan=False)`` writes
    standard JSON (``NaN`` and ``Infinity`` are not JSON, and most readers refuse them)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_ready(item) for item in value]
    return value
