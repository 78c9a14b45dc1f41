"""ROS 2 messages as ``rosbags`` builds and serialises them: one typestore, and each message built
from the fields given with every other field at its ROS default (zero, empty).

The typestore is ROS 2 Humble's (:data:`STORE`): the message definitions written into a bag are its,
so ``ros2 bag`` on Humble and later, Foxglove and any MCAP reader decode them. ``rosbags`` is
imported here and in the bag modules only, when a bag is written or read.
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np

from ..geometry.frames import quaternion_yaw_deg, yaw_quaternion

#: The message definitions of bags we write, and the fallback for bags that carry none.
STORE = "ROS2_HUMBLE"

_NUMPY = {"bool": np.bool_, "byte": np.uint8, "char": np.uint8, "int8": np.int8, "uint8": np.uint8,
          "int16": np.int16, "uint16": np.uint16, "int32": np.int32, "uint32": np.uint32, "int64": np.int64,
          "uint64": np.uint64, "float32": np.float32, "float64": np.float64}


@lru_cache(maxsize=1)
def typestore() -> Any:
    from rosbags.typesys import Stores, get_typestore

    return get_typestore(getattr(Stores, STORE))


def _default(node: tuple[Any, Any]) -> Any:
    kind, detail = node
    name = getattr(kind, "name", str(kind))
    if name == "BASE":
        base = detail[0]
        return "" if base == "string" else False if base == "bool" else 0.0 if base.startswith("float") else 0
    if name == "NAME":
        return build(detail)
    inner, length = detail
    if getattr(inner[0], "name", "") == "BASE" and inner[1][0] in _NUMPY:
        return np.zeros(length if name == "ARRAY" else 0, dtype=_NUMPY[inner[1][0]])
    return [_default(inner) for _ in range(length)] if name == "ARRAY" else []


def build(typename: str, **values: Any) -> Any:
    """A ``typename`` message (``pkg/msg/Name``) with ``values`` and ROS defaults for the rest."""
    store = typestore()
    fields = store.fielddefs[typename][1]
    known = {name for name, _ in fields}
    unknown = set(values) - known
    if unknown:
        raise TypeError(f"{typename} has no field {', '.join(sorted(unknown))}")
    kwargs = {name: _value(node, values[name]) if name in values else _default(node) for name, node in fields}
    return store.types[typename](**kwargs)


def _value(node: tuple[Any, Any], value: Any) -> Any:
    """``value`` as rosbags wants it: a sequence of numbers as a numpy array of the field's type."""
    kind, detail = node
    if getattr(kind, "name", "") in ("ARRAY", "SEQUENCE") and getattr(detail[0][0], "name", "") == "BASE" \
            and detail[0][1][0] in _NUMPY and not isinstance(value, np.ndarray):
        return np.asarray(value, dtype=_NUMPY[detail[0][1][0]])
    return value


def stamp(ns: int) -> Any:
    """A ``builtin_interfaces/Time`` of ``ns`` nanoseconds."""
    return build("builtin_interfaces/msg/Time", sec=int(ns // 1_000_000_000), nanosec=int(ns % 1_000_000_000))


def header(ns: int, frame: str) -> Any:
    return build("std_msgs/msg/Header", stamp=stamp(ns), frame_id=frame)


def seconds(time: Any) -> float:
    """A ``builtin_interfaces/Time`` in seconds."""
    return float(time.sec) + float(time.nanosec) * 1e-9


def quaternion(yaw_deg: float) -> Any:
    x, y, z, w = yaw_quaternion(yaw_deg)
    return build("geometry_msgs/msg/Quaternion", x=x, y=y, z=z, w=w)


def yaw_deg(q: Any) -> float:
    """The heading (degrees) of a quaternion about z (roll and pitch ignored)."""
    return quaternion_yaw_deg(q.x, q.y, q.z, q.w)


def point(x_m: float, y_m: float, z_m: float = 0.0) -> Any:
    return build("geometry_msgs/msg/Point", x=float(x_m), y=float(y_m), z=float(z_m))


def vector(x: float = 0.0, y: float = 0.0, z: float = 0.0) -> Any:
    return build("geometry_msgs/msg/Vector3", x=float(x), y=float(y), z=float(z))


def color(r: float, g: float, b: float, a: float = 1.0) -> Any:
    return build("std_msgs/msg/ColorRGBA", r=r, g=g, b=b, a=a)


def serialize(message: Any, typename: str) -> bytes:
    return bytes(typestore().serialize_cdr(message, typename))
