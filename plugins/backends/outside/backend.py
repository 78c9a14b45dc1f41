"""The ``outside`` backend and robot themselves: one answers nothing, the other is not here (the package
docstring says why)."""

from __future__ import annotations

from safeembodai_core.contracts.components import LLMBackend
from safeembodai_core.errors import BackendError, EnvironmentError_

from .options import OutsideOptions, OutsideRobotOptions


class OutsideBackend(LLMBackend):
    """Answers nothing: the commands of a served room come over the wire."""

    def __init__(self, options: OutsideOptions) -> None:
        self.options = options

    def complete(self, prompt, rng):
        raise BackendError("backend 'outside': the commands of a served room came from a client outside this "
                           "process; it cannot answer a prompt (choose an LLM backend to run this scenario)")


class OutsideRobot:
    """The robot of a guard-mcp session: outside this process, never simulated; building it says so."""

    def __init__(self, options: OutsideRobotOptions) -> None:
        where = f" at {options.rosbridge}" if options.rosbridge else ""
        raise EnvironmentError_(f"environment 'outside': the robot{where} was outside this process (a guard-mcp "
                                "session records its calls); there is nothing here to simulate or replay")
