"""``safeembodai view``: every run in a browser -- an index of run folders, a page per run (its
metrics, figures and a filterable table of trials) and a page per trial (its picture and step
timeline: what the LLM saw and was sent, what it answered, what the guard refused and why, what ran,
what it hit, the attacks injected). Static, self-contained and safe to open on hostile runs
(:mod:`.html`); ``--serve`` serves it on 127.0.0.1 and picks up new runs while they are written
(:mod:`.serve`).
"""

from .site import build_site

__all__ = ["build_site"]
