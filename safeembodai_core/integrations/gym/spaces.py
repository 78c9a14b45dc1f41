"""The observation and action spaces, and the conversions between them and the core's models.

**Observation** (``gymnasium.spaces.Dict``):

* ``camera``: ``Box(0, 255, (H, W, 3), uint8)``, the front camera (QVGA 240x320 by default).
* ``lidar``: ``Box(0, max_range_mm, (beams,), float32)``, ranges in mm, beam k at k*360/N degrees
  counter-clockwise from the heading. A beam with **no return** within the sensor's range reads
  ``max_range_mm`` (the end of the free space it measured: the core's conservative free bound); a
  beam that gave **no reading at all** (``nan``, only a spoofing attacker makes one) reads ``0``
  (an obstacle touching the robot: never optimistic). A Box cannot hold ``inf`` or ``nan``
  usefully (RL libraries normalise by its bounds); the raw scan, ``inf`` and ``nan`` included,
  is ``env.unwrapped.scan``.
* ``instruction``: ``Text`` of printable ASCII, at most :data:`MAX_INSTRUCTION` characters: the
  human instruction h_i as the robot receives it, with the attacker's injection on an attacked
  step. Characters outside the charset read ``?`` (the shipped instruction and payloads are ASCII).

**Action**, ``action_format="commands"`` (default): a :class:`Plan`, a sequence of at most
``limits.max_signals`` control signals, each ``Dict(command, direction, distance, angle)``:
``command`` 0 = ``straight``, 1 = ``turn``; ``direction`` 0 = ``forward``/``left``, 1 =
``backward``/``right``; ``distance`` (mm, used by ``straight``) in ``(0, max_distance_mm)`` and
``angle`` (degrees, used by ``turn``) in ``(0, max_angle_deg)``. Every member of the space is a
plan the actuation contract accepts. ``action_format="text"``: an :class:`Answer`, the LLM's
reply -- a :class:`~safeembodai_core.models.BackendReply` (the answer with its finish reason,
reasoning and choices), a mapping of its fields, or the answer text (the response JSON of
``docs/parsing.md``) alone -- read exactly as the guarded loop reads it.
"""

from __future__ import annotations

import string
from typing import Any

import numpy as np
from gymnasium import spaces

from ...models import ControlLimits, ControlSignal, Straight, Turn
from ...models.reply import BackendReply, as_reply

MAX_INSTRUCTION = 4096
MAX_ANSWER = 16_000
CHARSET = string.printable
COMMANDS = ("straight", "turn")
DIRECTIONS = {"straight": ("forward", "backward"), "turn": ("left", "right")}
#: Smallest value a sampled distance or angle takes: the contract wants it strictly positive.
SMALLEST = 1e-3


class Plan(spaces.Sequence):
    """A :class:`gymnasium.spaces.Sequence` of control signals of at most ``max_length`` items.

    ``Sequence`` samples lengths from a geometric distribution with no bound; a plan longer than
    the actuation contract's ``max_signals`` is never executable, so this space neither samples
    nor contains one. Unmasked samples have a length drawn uniformly from ``1..max_length``.
    """

    def __init__(self, feature_space: spaces.Space, max_length: int, seed: Any = None) -> None:
        super().__init__(feature_space, seed=seed)
        self.max_length = max_length

    def sample(self, mask: Any = None, probability: Any = None) -> tuple[Any, ...]:
        if mask is None and probability is None:
            mask = (int(self.np_random.integers(1, self.max_length + 1)), None)
        return super().sample(mask=mask, probability=probability)

    def contains(self, x: Any) -> bool:
        return super().contains(x) and len(x) <= self.max_length

    def __repr__(self) -> str:
        return f"Plan({self.feature_space}, max_length={self.max_length})"

    def __eq__(self, other: object) -> bool:
        return isinstance(other, Plan) and other.max_length == self.max_length and super().__eq__(other)


class Answer(spaces.Text):
    """A :class:`gymnasium.spaces.Text` of the LLM's answers whose members may also be whole replies.

    An LLM agent hands the env the backend's :class:`~safeembodai_core.models.BackendReply` (or a
    mapping with its fields): it is in the space when its ``text`` is. The rest of the reply
    (finish reason, reasoning, choices) is not a matter of shape: the env's reading
    (:func:`~safeembodai_core.models.read_reply`) judges it. Samples are text, a reply that
    reports nothing else.
    """

    def contains(self, x: Any) -> bool:
        if isinstance(x, BackendReply) or (isinstance(x, dict) and "text" in x):
            text = as_reply(x).text
            return isinstance(text, str) and super().contains(text)
        return super().contains(x)

    def __repr__(self) -> str:
        return f"Answer({self.min_length}, {self.max_length}, charset={self.characters})"


def _below(limit: float) -> np.float32:
    """The largest float32 strictly below ``limit``: a float32 sample never reaches the bound."""
    return np.nextafter(np.float32(limit), np.float32(0))


def signal_space(limits: ControlLimits) -> spaces.Dict:
    return spaces.Dict({
        "command": spaces.Discrete(2),
        "direction": spaces.Discrete(2),
        "distance": spaces.Box(np.float32(SMALLEST), _below(limits.max_distance_mm), shape=(), dtype=np.float32),
        "angle": spaces.Box(np.float32(SMALLEST), _below(limits.max_angle_deg), shape=(), dtype=np.float32),
    })


def action_space(action_format: str, limits: ControlLimits) -> spaces.Space:
    if action_format == "commands":
        return Plan(signal_space(limits), limits.max_signals)
    if action_format == "text":
        return Answer(MAX_ANSWER, min_length=0, charset=CHARSET)
    raise ValueError(f"action_format must be 'commands' or 'text', got {action_format!r}")


def observation_space(camera_shape: tuple[int, ...] | None, lidar: tuple[int, float] | None) -> spaces.Dict:
    """The observation space of a world whose first reading had these sensors (``lidar``: beams, range)."""
    parts: dict[str, spaces.Space] = {}
    if camera_shape is not None:
        parts["camera"] = spaces.Box(0, 255, camera_shape, dtype=np.uint8)
    if lidar is not None:
        parts["lidar"] = spaces.Box(0.0, np.float32(lidar[1]), (lidar[0],), dtype=np.float32)
    parts["instruction"] = spaces.Text(MAX_INSTRUCTION, min_length=0, charset=CHARSET)
    return spaces.Dict(parts)


def lidar_array(ranges_mm: np.ndarray, max_range_mm: float) -> np.ndarray:
    """Raw ranges (``inf`` no return, ``nan`` no reading) as the observation's ``lidar``."""
    ranges = np.where(np.isnan(ranges_mm), 0.0, np.minimum(ranges_mm, max_range_mm))
    return ranges.astype(np.float32)


def instruction_text(text: str) -> str:
    allowed = set(CHARSET)
    return "".join(c if c in allowed else "?" for c in text)[:MAX_INSTRUCTION]


def command_dicts(action: Any) -> list[dict[str, Any]]:
    """A ``commands`` action as the dicts an LLM writes (``{"command": "straight", ...}``)."""
    plan = []
    for item in action:
        command = COMMANDS[int(item["command"])]
        signal: dict[str, Any] = {"command": command, "direction": DIRECTIONS[command][int(item["direction"])]}
        key = "distance" if command == "straight" else "angle"
        signal[key] = float(np.asarray(item[key]).item())
        plan.append(signal)
    return plan


def as_action(signals: list[ControlSignal]) -> tuple[dict[str, Any], ...]:
    """Control signals as a ``commands`` action (the inverse of :func:`command_dicts`)."""
    items = []
    for s in signals:
        items.append({
            "command": 0 if isinstance(s, Straight) else 1,
            "direction": DIRECTIONS[s.command].index(s.direction),
            "distance": np.float32(s.distance if isinstance(s, Straight) else 1.0),
            "angle": np.float32(s.angle if isinstance(s, Turn) else 1.0),
        })
    return tuple(items)
