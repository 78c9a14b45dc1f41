"""Pages from templates, with everything a run folder holds treated as hostile text.

Every value reaches a page through Jinja2 with autoescaping on, after :func:`visible`: secrets
masked, control, bidi and zero-width characters shown as escapes (``\\u202e``), so what an LLM,
a scenario or a run folder wrote is read as text and never as markup, and never hides. Pages load
only their own stylesheet and script (``view.css``, ``view.js``) and images from the site itself,
as the Content-Security-Policy (:data:`CSP`) says -- in a ``<meta>`` tag, and as a header when
served -- so nothing is fetched from elsewhere and no script from data could run.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

from ..trust.text import terminal_text

#: The policy every page carries (as a ``<meta>`` tag; ``--serve`` also sends it, with
#: ``frame-ancestors``, as a header, the only place browsers read that directive).
CSP = ("default-src 'none'; img-src 'self'; style-src 'self'; script-src 'self'; base-uri 'none'; "
       "form-action 'none'")
CSP_HEADER = CSP + "; frame-ancestors 'none'"
STATIC = Path(__file__).with_name("static")


def visible(value: Any) -> str:
    """``value`` as text to show: redacted, invisible characters as escapes, line breaks kept."""
    return terminal_text("" if value is None else str(value), keep_layout=True)


@lru_cache(maxsize=1)
def environment() -> Any:
    from jinja2 import Environment, PackageLoader, StrictUndefined, select_autoescape

    env = Environment(loader=PackageLoader("safeembodai_core.view", "templates"),
                      autoescape=select_autoescape(default=True, default_for_string=True),
                      undefined=StrictUndefined, trim_blocks=True, lstrip_blocks=True)
    env.filters["visible"] = visible
    env.globals["CSP"] = CSP
    return env


def render(template: str, **values: Any) -> str:
    return environment().get_template(template).render(**values)
