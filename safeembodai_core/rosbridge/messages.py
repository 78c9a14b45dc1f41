"""The message types this server knows, checked field by field as rosbridge checks them.

A message a client publishes to a topic the server accepts is checked against its type's definition
before the server's handler sees it: a field the type does not have, a value of the wrong kind (text
for a number, a fractional or out-of-range integer, a number beyond ``float32``), a fixed-size array
of the wrong length are refused with the field's path (``msg.linear.x``). A missing field takes its
default, as rosbridge fills it (zero, empty, ``Quaternion.w`` = 1); a missing ``header`` or header
``stamp`` takes the server's current time, as rosbridge's ``publish`` does. Inside a ``float32[]`` or
``float64[]`` array ``null`` is allowed and kept: it is how rosbridge writes ``inf`` and ``NaN``
(REP 117 gives them meanings in a ``LaserScan``); a scalar number field must hold a number. A
``uint8[]`` field is base64 text (as rosbridge sends it) or a list of bytes.

:func:`typedefs` gives the same definitions in the shape ``/rosapi/message_details`` returns them.
"""

from __future__ import annotations

import base64
import binascii
import math
from dataclasses import dataclass
from typing import Any

from ..trust.quoting import quote_untrusted

_INTEGERS = {"int8": (-2**7, 2**7 - 1), "uint8": (0, 2**8 - 1), "int16": (-2**15, 2**15 - 1),
             "uint16": (0, 2**16 - 1), "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1),
             "int64": (-2**63, 2**63 - 1), "uint64": (0, 2**64 - 1)}
_FLOATS = {"float32": 3.4028234663852886e38, "float64": math.inf}
NOW = object()  # a default that is the server's current time (a header's stamp)


@dataclass(frozen=True)
class Field:
    """One field of a message type: ``arraylen`` -1 for a single value, 0 for a list, n for n values."""

    name: str
    type: str
    arraylen: int = -1
    default: Any = None


def _xyz(*names: str, default: float = 0.0) -> tuple[Field, ...]:
    return tuple(Field(name, "float64", default=default) for name in names)


_HEADER = Field("header", "std_msgs/msg/Header")
MESSAGE_TYPES: dict[str, tuple[Field, ...]] = {
    "builtin_interfaces/msg/Time": (Field("sec", "int32"), Field("nanosec", "uint32")),
    "std_msgs/msg/Header": (Field("stamp", "builtin_interfaces/msg/Time", default=NOW), Field("frame_id", "string")),
    "std_msgs/msg/String": (Field("data", "string"),),
    "geometry_msgs/msg/Vector3": _xyz("x", "y", "z"),
    "geometry_msgs/msg/Point": _xyz("x", "y", "z"),
    "geometry_msgs/msg/Quaternion": _xyz("x", "y", "z") + _xyz("w", default=1.0),
    "geometry_msgs/msg/Pose": (Field("position", "geometry_msgs/msg/Point"),
                               Field("orientation", "geometry_msgs/msg/Quaternion")),
    "geometry_msgs/msg/PoseWithCovariance": (Field("pose", "geometry_msgs/msg/Pose"),
                                             Field("covariance", "float64", 36)),
    "geometry_msgs/msg/Twist": (Field("linear", "geometry_msgs/msg/Vector3"),
                                Field("angular", "geometry_msgs/msg/Vector3")),
    "geometry_msgs/msg/TwistStamped": (_HEADER, Field("twist", "geometry_msgs/msg/Twist")),
    "geometry_msgs/msg/TwistWithCovariance": (Field("twist", "geometry_msgs/msg/Twist"),
                                              Field("covariance", "float64", 36)),
    "nav_msgs/msg/Odometry": (_HEADER, Field("child_frame_id", "string"),
                              Field("pose", "geometry_msgs/msg/PoseWithCovariance"),
                              Field("twist", "geometry_msgs/msg/TwistWithCovariance")),
    "sensor_msgs/msg/LaserScan": (_HEADER, *(Field(name, "float32") for name in (
        "angle_min", "angle_max", "angle_increment", "time_increment", "scan_time", "range_min", "range_max")),
        Field("ranges", "float32", 0), Field("intensities", "float32", 0)),
    "sensor_msgs/msg/CompressedImage": (_HEADER, Field("format", "string"), Field("data", "uint8", 0)),
}


class MessageError(ValueError):
    """A message that does not fit its type; the text names the field's path and what was wrong."""


def _kind(value: Any) -> str:
    return {bool: "a boolean", str: "text", dict: "an object", list: "an array", type(None): "null"}.get(
        type(value), "a number")


def _default(field: Field, stamp: dict[str, int]) -> Any:
    if field.arraylen == 0:
        return "" if field.type == "uint8" else []
    if field.arraylen > 0:
        return [_default(Field(field.name, field.type), stamp) for _ in range(field.arraylen)]
    if field.default is NOW:
        return dict(stamp)
    if field.type in MESSAGE_TYPES:
        return {inner.name: _default(inner, stamp) for inner in MESSAGE_TYPES[field.type]}
    if field.default is not None:
        return field.default
    return {"bool": False, "string": ""}.get(field.type, 0.0 if field.type in _FLOATS else 0)


def _atomic(type_name: str, value: Any, path: str, in_array: bool) -> Any:
    if type_name == "bool" and isinstance(value, bool):
        return value
    if type_name == "string" and isinstance(value, str):
        return value
    if type_name in _INTEGERS and isinstance(value, int) and not isinstance(value, bool):
        low, high = _INTEGERS[type_name]
        if not low <= value <= high:
            raise MessageError(f"{path}: {value} is out of the range of {type_name} [{low}, {high}]")
        return value
    if type_name in _FLOATS and isinstance(value, (int, float)) and not isinstance(value, bool):
        if not abs(value) <= _FLOATS[type_name]:
            raise MessageError(f"{path}: {value:g} is beyond the range of {type_name}")
        return value
    if type_name in _FLOATS and value is None and in_array:
        return None  # rosbridge's inf / NaN
    wanted = {"bool": "a boolean", "string": "text"}.get(type_name, f"a number ({type_name})")
    if type_name in _INTEGERS and isinstance(value, float):
        wanted = f"a whole number ({type_name})"
    raise MessageError(f"{path}: {wanted} is required, not {_kind(value)}")


def _bytes(value: Any, path: str) -> Any:
    if isinstance(value, str):
        try:
            base64.b64decode(value, validate=True)
        except binascii.Error:
            raise MessageError(f"{path}: uint8[] text must be base64") from None
        return value
    if isinstance(value, list):
        return [_atomic("uint8", item, f"{path}[{index}]", True) for index, item in enumerate(value)]
    raise MessageError(f"{path}: uint8[] must be base64 text or an array of bytes, not {_kind(value)}")


def _value(field: Field, value: Any, path: str, stamp: dict[str, int]) -> Any:
    if field.arraylen >= 0:
        if field.type == "uint8" and field.arraylen == 0:
            return _bytes(value, path)
        if not isinstance(value, list):
            raise MessageError(f"{path}: an array is required, not {_kind(value)}")
        if field.arraylen and len(value) != field.arraylen:
            raise MessageError(f"{path}: exactly {field.arraylen} values are required, not {len(value)}")
        single = Field(field.name, field.type)
        return [_one(single, item, f"{path}[{index}]", stamp, True) for index, item in enumerate(value)]
    return _one(field, value, path, stamp, False)


def _one(field: Field, value: Any, path: str, stamp: dict[str, int], in_array: bool) -> Any:
    if field.type in MESSAGE_TYPES:
        return conform(field.type, value, stamp, path)
    return _atomic(field.type, value, path, in_array)


def time_of(seconds: float) -> dict[str, int]:
    """``seconds`` since the epoch as a ``builtin_interfaces/msg/Time``."""
    sec = int(seconds // 1)
    return {"sec": sec, "nanosec": min(int((seconds - sec) * 1e9), 999_999_999)}


def is_known(type_name: str) -> bool:
    """Whether this server has the definition of ``type_name`` (``pkg/msg/Type``)."""
    return type_name in MESSAGE_TYPES


def conform(type_name: str, msg: Any, stamp: dict[str, int], path: str = "msg") -> dict[str, Any]:
    """``msg`` checked against the known type ``type_name``, with its missing fields filled in.

    :param stamp: the ``builtin_interfaces/msg/Time`` a missing header stamp takes.
    :raises MessageError: the first field that does not fit, by its path.
    """
    if not isinstance(msg, dict):
        raise MessageError(f"{path}: a {type_name} must be an object, not {_kind(msg)}")
    fields = MESSAGE_TYPES[type_name]
    names = {field.name for field in fields}
    for key in msg:
        if key not in names:
            raise MessageError(f"{path}: {type_name} has no field {quote_untrusted(key, 60)}")
    return {field.name: _value(field, msg[field.name], f"{path}.{field.name}", stamp) if field.name in msg
            else _default(field, stamp) for field in fields}


def _example(field: Field) -> str:
    if field.arraylen >= 0:
        return "[]"
    if field.type in MESSAGE_TYPES:
        return "{}"
    return str(_default(field, {}))


def typedefs(type_name: str) -> list[dict[str, Any]]:
    """``/rosapi/message_details``'s answer: the type's typedef, then each type it holds, once each
    (rosapi's order); empty for a type this server does not know."""
    found: list[dict[str, Any]] = []
    pending = [type_name]
    seen: set[str] = set()
    while pending:
        name = pending.pop(0)
        if name in seen or name not in MESSAGE_TYPES:
            continue
        seen.add(name)
        fields = MESSAGE_TYPES[name]
        found.append({"type": name, "fieldnames": [f.name for f in fields], "fieldtypes": [f.type for f in fields],
                      "fieldarraylen": [f.arraylen for f in fields], "examples": [_example(f) for f in fields],
                      "constnames": [], "constvalues": []})
        pending[:0] = [f.type for f in fields if f.type in MESSAGE_TYPES]
    return found
