"""``scripted``: replays answers given in its options, for tests and reproducible demos.

Each trial builds a fresh backend, so every trial replays from the first answer. Entries may be
JSON objects (sent as JSON text) or raw strings (sent as is, malformed or not). After the last
entry it repeats the last (``then: repeat``) or fails like an outage (``then: fail``). It reports
no token usage: it sends nothing anywhere.
"""

from __future__ import annotations

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy

from .options import ScriptedOptions


@hookimpl
def register_llm_backends(register):
    register("scripted", lazy(f"{__name__}.replay", "ScriptedBackend"), options=ScriptedOptions,
             description="replays answers from its options (tests, demos)")
