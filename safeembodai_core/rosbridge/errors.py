"""The errors the rosbridge server and client raise to their caller."""

from __future__ import annotations

from ..errors import SafeEmbodAIError


class RosbridgeError(SafeEmbodAIError):
    """The server cannot listen (the port is taken), or the client cannot reach or lost its server."""


class ServiceCallError(RosbridgeError):
    """A service call answered ``result: false`` (the text is the server's reason), or timed out."""
