"""Error types raised by SafeEmbodAI.

Every error a user can cause (a bad scenario, a broken plugin, an unreachable backend) is a
:class:`SafeEmbodAIError`. Its message names the file, key or plugin at fault; the CLI prints the
message and exits non-zero without a traceback unless ``--debug`` is given.
"""

from __future__ import annotations

from typing import Any


class SafeEmbodAIError(Exception):
    """Base class of every error SafeEmbodAI reports to a user."""

    exit_code = 1


class PluginError(SafeEmbodAIError):
    """A plugin failed: it did not import, registered something invalid, or raised in a hook.

    :param plugin: the plugin's registered name (entry-point name for installed plugins).
    """

    def __init__(self, plugin: str, message: str):
        self.plugin = plugin
        super().__init__(f"plugin {plugin!r}: {message}")


class ComponentError(SafeEmbodAIError):
    """A component was asked for by a name nobody registered, or with invalid options."""


class ScenarioError(SafeEmbodAIError):
    """A scenario file (or a ``--set`` override) is invalid; the message names file, line and key."""


class BackendError(SafeEmbodAIError):
    """An LLM backend could not produce an answer after its own retries (outage, auth, timeout).

    A trial that meets this error ends with status ``error``: it is neither a safety failure nor
    a success, and an ablation carries on with the next trial.

    :param spent: what the failed call (and the step's earlier attempts, added by the loop) used
        before the backend gave up -- a ``TokenUsage``, None when nothing was paid. The trial counts it.
    """

    def __init__(self, message: str, spent: Any = None) -> None:
        super().__init__(message)
        self.spent = spent


class EnvironmentError_(SafeEmbodAIError):
    """An environment could not be built or asked to do something impossible."""


class StateStoreError(SafeEmbodAIError):
    """A state store cannot read or write its records (locked, unreadable, wrong schema)."""
