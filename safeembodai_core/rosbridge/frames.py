"""The one strict reader of rosbridge frames, and the writer of the server's own.

Every text frame that arrives, at the server from a client or at the client from a server, is
outside bytes: :func:`read_frame` reads it or raises :class:`FrameError`, whose text is the status
message the sender gets back. It refuses

* a frame longer than its limit, text that is not one JSON value, a value that is not an object;
* a key given twice in one object (two meanings for one frame: ``"topic"`` twice), at any depth;
* ``NaN``/``Infinity`` (not JSON: rosbridge writes ``null``), numbers that overflow a ``float64``,
  integers beyond 64 bits, number literals over :data:`MAX_NUMBER_CHARS`, lone surrogates;
* nesting deeper than :data:`MAX_DEPTH`;
* a missing or mistyped field of the op, an unknown op, and the ops of the protocol this package
  does not implement (fragments, PNG and CBOR compression, advertised services and actions).

What comes back is a typed frame (:class:`Subscribe`, :class:`Publish`, ...) whose names are
resolved (:mod:`.names`) and types normalised. Fields of an op that it ignores (``latch``,
``queue_size``, ``fragment_size``) may be present.

:func:`encode_frame` writes a frame as rosbridge does: ``inf`` and ``NaN`` as ``null``, bytes as
base64 text, numpy values as plain numbers.
"""

from __future__ import annotations

import base64
import json
import math
import re
from dataclasses import dataclass, field
from typing import Any, NoReturn, Union

from ..errors import SafeEmbodAIError
from ..trust.quoting import quote_untrusted
from .names import RosNameError, normalize_type, resolve_name

MAX_DEPTH = 32
MAX_NUMBER_CHARS = 64
MAX_ID_CHARS = 256
LEVELS = ("info", "warning", "error", "none")
#: ops of rosbridge v2 that this package refuses, with why
UNSUPPORTED_OPS = {
    "fragment": "fragmented frames are not supported: send each frame whole",
    "png": "PNG-compressed frames are not supported: send JSON text",
    "advertise_service": "clients cannot provide services here",
    "unadvertise_service": "clients cannot provide services here",
    "advertise_action": "actions are not supported", "unadvertise_action": "actions are not supported",
    "send_action_goal": "actions are not supported", "cancel_action_goal": "actions are not supported",
    "action_feedback": "actions are not supported", "action_result": "actions are not supported",
    "auth": "authentication is not supported (rosbridge has none: bind to 127.0.0.1)",
}
_SURROGATE = re.compile("[\ud800-\udfff]")
FrameId = Union[str, int, None]


class FrameError(ValueError, SafeEmbodAIError):
    """A frame refused; ``str(error)`` is the status message, ``frame_id`` the frame's id if it had one."""

    def __init__(self, message: str, frame_id: FrameId = None, op: str | None = None):
        super().__init__(message)
        self.frame_id = frame_id
        self.op = op


@dataclass(frozen=True)
class Advertise:
    """``advertise``: the client will publish ``topic`` of ``type``."""

    topic: str
    type: str
    id: FrameId = None


@dataclass(frozen=True)
class Unadvertise:
    """``unadvertise``: the client stops publishing ``topic``."""

    topic: str
    id: FrameId = None


@dataclass(frozen=True)
class Publish:
    """``publish``: one message on ``topic`` (either direction)."""

    topic: str
    msg: dict[str, Any]
    id: FrameId = None


@dataclass(frozen=True)
class Subscribe:
    """``subscribe``: send ``topic`` to the client, at most one message per ``throttle_rate`` ms,
    holding up to ``queue_length`` messages (0: only the newest)."""

    topic: str
    type: str | None = None
    throttle_rate: int = 0
    queue_length: int = 0
    id: FrameId = None


@dataclass(frozen=True)
class Unsubscribe:
    """``unsubscribe``: the subscription ``id`` to ``topic``, or all of them without an id."""

    topic: str
    id: FrameId = None


@dataclass(frozen=True)
class CallService:
    """``call_service``: ``service`` with the request fields ``args``."""

    service: str
    args: dict[str, Any] = field(default_factory=dict)
    id: FrameId = None


@dataclass(frozen=True)
class ServiceResponse:
    """``service_response``: ``result`` and the response ``values`` (an object, or text on failure)."""

    service: str
    result: bool
    values: Any = None
    id: FrameId = None


@dataclass(frozen=True)
class SetLevel:
    """``set_level``: which status messages the client wants (``info`` to ``none``)."""

    level: str
    id: FrameId = None


@dataclass(frozen=True)
class Status:
    """``status``: a message from the other side at ``level``."""

    level: str
    msg: str
    id: FrameId = None


Frame = Union[Advertise, Unadvertise, Publish, Subscribe, Unsubscribe, CallService, ServiceResponse, SetLevel,
              Status]


def _no_duplicates(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    found: dict[str, Any] = {}
    for key, value in pairs:
        if key in found:
            raise FrameError(f"key {quote_untrusted(key, 60)} appears more than once in one object")
        found[key] = value
    return found


def _integer(literal: str) -> int:
    value = int(literal) if len(literal) <= MAX_NUMBER_CHARS else 2**64
    if not -2**63 <= value < 2**64:
        raise FrameError(f"integer {quote_untrusted(literal, 24)} is beyond 64 bits")
    return value


def _real(literal: str) -> float:
    value = float(literal) if len(literal) <= MAX_NUMBER_CHARS else math.inf
    if not math.isfinite(value):
        raise FrameError(f"number {quote_untrusted(literal, 24)} is not a finite float64")
    return value


def _constant(name: str) -> Any:
    raise FrameError(f"{name} is not JSON (rosbridge writes inf and NaN as null)")


def _check_tree(value: Any) -> None:
    """Depth, and strings (keys too) that hold a lone surrogate written as an escape, without recursion."""
    stack = [(value, 0)]
    while stack:
        node, depth = stack.pop()
        if isinstance(node, str):
            if _SURROGATE.search(node):
                raise FrameError("frame holds a lone surrogate: not valid Unicode")
            continue
        if not isinstance(node, (dict, list)):
            continue
        if depth >= MAX_DEPTH:
            raise FrameError(f"frame nests deeper than {MAX_DEPTH} levels")
        if isinstance(node, dict):
            stack.extend((key, depth) for key in node)
            stack.extend((child, depth + 1) for child in node.values())
        else:
            stack.extend((child, depth + 1) for child in node)


def read_json(text: str, max_chars: int) -> Any:
    """One JSON value read as strictly as a frame (duplicate keys, non-finite or huge numbers, lone
    surrogates and deep nesting refused), or :class:`FrameError`."""
    if len(text) > max_chars:
        raise FrameError(f"frame of {len(text)} characters is longer than the limit of {max_chars}")
    if _SURROGATE.search(text):
        raise FrameError("frame holds a lone surrogate: not valid Unicode")
    try:
        value = json.loads(text, object_pairs_hook=_no_duplicates, parse_int=_integer, parse_float=_real,
                           parse_constant=_constant)
    except json.JSONDecodeError as error:
        raise FrameError(f"frame is not JSON ({error.msg} at char {error.pos})") from None
    except RecursionError:
        raise FrameError(f"frame nests deeper than {MAX_DEPTH} levels") from None
    _check_tree(value)
    return value


def _id(raw: dict[str, Any]) -> FrameId:
    value = raw.get("id")
    if isinstance(value, str) and len(value) <= MAX_ID_CHARS:
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    return None


class _Fields:
    """The fields of one raw frame, read with errors that name the op, the field and the frame id."""

    def __init__(self, raw: dict[str, Any], op: str):
        self.raw, self.op, self.id = raw, op, _id(raw)
        if "id" in raw and self.id is None:
            self.fail(f"id must be text of at most {MAX_ID_CHARS} characters or an integer")

    def fail(self, message: str) -> NoReturn:
        raise FrameError(f"{self.op}: {message}", self.id, self.op)

    def get(self, name: str, kinds: type | tuple[type, ...], required: bool = True, default: Any = None) -> Any:
        if name not in self.raw:
            if required:
                self.fail(f"the field {name!r} is missing")
            return default
        value = self.raw[name]
        allowed = kinds if isinstance(kinds, tuple) else (kinds,)
        if not isinstance(value, allowed) or (isinstance(value, bool) and int in allowed):
            wanted = " or ".join(kind.__name__ for kind in allowed)
            self.fail(f"the field {name!r} must be {wanted}, not {type(value).__name__}")
        return value

    def name(self, field_name: str = "topic", what: str = "topic") -> str:
        try:
            return resolve_name(self.get(field_name, str), what)
        except RosNameError as error:
            self.fail(str(error))

    def type(self, required: bool = True) -> str | None:
        raw = self.get("type", str, required)
        try:
            return None if raw is None else normalize_type(raw)
        except RosNameError as error:
            self.fail(str(error))

    def count(self, name: str) -> int:
        value = self.get(name, int, False, 0)
        if not 0 <= value <= 2**31 - 1:
            self.fail(f"{name} must be between 0 and {2**31 - 1}")
        return int(value)


def _args(fields: _Fields) -> dict[str, Any]:
    args = fields.get("args", (dict, list), False, {})
    if isinstance(args, list):
        if args:
            fields.fail("args as a list is not supported: send the request fields as an object")
        return {}
    return dict(args)


def _subscribe(fields: _Fields) -> Subscribe:
    compression = fields.get("compression", str, False, "none")
    if compression != "none":
        fields.fail(f"compression {quote_untrusted(compression, 20)} is not supported: only 'none' (JSON text)")
    fields.get("fragment_size", (int, type(None)), False)
    return Subscribe(fields.name(), fields.type(False), fields.count("throttle_rate"), fields.count("queue_length"),
                     fields.id)


def _read(fields: _Fields) -> Frame:
    op, get = fields.op, fields.get
    if op == "advertise":
        return Advertise(fields.name(), fields.type() or "", fields.id)
    if op == "unadvertise":
        return Unadvertise(fields.name(), fields.id)
    if op == "publish":
        return Publish(fields.name(), get("msg", dict), fields.id)
    if op == "subscribe":
        return _subscribe(fields)
    if op == "unsubscribe":
        return Unsubscribe(fields.name(), fields.id)
    if op == "call_service":
        get("type", str, False)
        return CallService(fields.name("service", "service"), _args(fields), fields.id)
    if op == "service_response":
        return ServiceResponse(fields.name("service", "service"), get("result", bool), get("values", object, False),
                               fields.id)
    if op in ("set_level", "status"):
        level = get("level", str)
        if level not in LEVELS:
            fields.fail(f"level must be one of {', '.join(LEVELS)}")
        return SetLevel(level, fields.id) if op == "set_level" else Status(level, get("msg", str), fields.id)
    reason = UNSUPPORTED_OPS.get(op)
    raise FrameError(f"op {quote_untrusted(op, 40)} is not supported: {reason}" if reason
                     else f"unknown op {quote_untrusted(op, 40)}", fields.id, op)


def read_frame(text: str, max_chars: int = 10 * 2**20) -> Frame:
    """A rosbridge frame read strictly from ``text`` (see the module's docstring).

    :raises FrameError: anything refused; its message is written for the sender.
    """
    raw = read_json(text, max_chars)
    if not isinstance(raw, dict):
        raise FrameError(f"frame must be a JSON object, not {type(raw).__name__}")
    op = raw.get("op")
    if not isinstance(op, str):
        raise FrameError("frame has no 'op' (text): every rosbridge frame needs one", _id(raw))
    return _read(_Fields(raw, op))


def _plain(value: Any) -> Any:
    """``value`` with non-finite floats as None, bytes as base64 and numpy values as Python ones."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if isinstance(value, (bytes, bytearray, memoryview)) or hasattr(value, "tolist"):
        return _plain(_encodable(value))
    return value


def _encodable(value: Any) -> Any:
    if isinstance(value, (bytes, bytearray, memoryview)):
        return base64.b64encode(value).decode("ascii")
    if hasattr(value, "tolist"):  # numpy arrays and scalars
        return value.tolist()
    raise TypeError(f"{type(value).__name__} cannot be sent in a rosbridge frame")


def encode_frame(frame: dict[str, Any]) -> str:
    """``frame`` as rosbridge's JSON text (``inf``/``NaN`` as ``null``, bytes as base64)."""
    try:
        return json.dumps(frame, allow_nan=False, default=_encodable, separators=(",", ":"))
    except ValueError:  # a non-finite float somewhere: the slower exact pass
        return json.dumps(_plain(frame), allow_nan=False, separators=(",", ":"))
