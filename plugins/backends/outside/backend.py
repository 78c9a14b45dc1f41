"""The ``outside`` backend itself: it answers nothing (the package docstring says why)."""

from __future__ import annotations

from safeembodai_core.components import LLMBackend
from safeembodai_core.errors import BackendError

from .options import OutsideOptions


class OutsideBackend(LLMBackend):
    """Answers nothing: the commands of a served room come over the wire."""

    def __init__(self, options: OutsideOptions) -> None:
        self.options = options

    def complete(self, prompt, rng):
        raise BackendError("backend 'outside': the commands of a served room came from a client outside this "
                           "process; it cannot answer a prompt (choose an LLM backend to run this scenario)")
