"""The rosbridge v2 protocol, without ROS: a server for a process that is a robot, a client for a node.

* :class:`RosbridgeServer` (:mod:`.server`) serves topics, accepts published messages and answers
  services and the rosapi services over a WebSocket, in a thread of its own.
* :class:`RosbridgeClient` (:mod:`.client`) connects to any rosbridge server (a real robot's too).
* :func:`read_frame` (:mod:`.frames`) is the one strict reader of every frame either receives.

Nothing here knows a room or a guard: ``serve-robot`` and ``guard-node`` are built on it. The
protocol as implemented, its limits and refusals: ``docs/rosbridge.md``.
"""

from importlib import import_module
from typing import TYPE_CHECKING, Any

_EXPORTS = {
    "RosbridgeServer": "server", "RosbridgeClient": "client", "RosbridgeError": "errors",
    "ServiceCallError": "errors", "FrameError": "frames", "read_frame": "frames",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(import_module(f".{module}", __name__), name)


if TYPE_CHECKING:  # pragma: no cover
    from .client import RosbridgeClient  # noqa: F401
    from .errors import RosbridgeError, ServiceCallError  # noqa: F401
    from .frames import FrameError, read_frame  # noqa: F401
    from .server import RosbridgeServer  # noqa: F401
