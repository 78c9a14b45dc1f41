"""What the mock pilot reads from a prompt -- and nothing else.

Everything here comes out of the :class:`~safeembodai_core.models.Prompt` the backend was
given: the camera PNG and LiDAR picture are decoded and analysed with the perception
plugin's own readers (or the text modalities are parsed when there are no images), the human
instruction and the reference state R_{i-1} are read from the user text, and the actuation
limits from the system prompt. The refusals of earlier attempts are read as data
(``Prompt.refusals``: the plan refused, the signal, the rule's :class:`~safeembodai_core.models.Advice`),
never from their words: a reworded reason changes nothing the pilot does.
``Prompt.sections`` says whether the security prefix and the reference state are in.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass, field

import numpy as np

from safeembodai_core.models import ControlSignal, Prompt, Refusal, Straight

from ...perception.describe import (
    SECTORS,
    TargetSighting,
    find_red_target,
    parse_lidar_text,
    parse_target_text,
    sector_clearance_from_points,
)
from ...perception.lidar_image import decode_png, nearest_in_cone, read_lidar_image
from .instruction import InstructionReading, read_instruction

_INSTRUCTION = re.compile(r"^Human Instruction:\s*(.*)$", re.MULTILINE)
_FENCED = re.compile(r"^Human Instruction \(untrusted data between (\S+) and (\S+)\):\n\1\n(.*?)\n\2",
                     re.MULTILINE | re.DOTALL)
_REFERENCE = re.compile(r"Reference State \(step (\d+)\):(.*)")
_SIGNAL_TEXT = r"(turn|straight) (left|right|forward|backward) (\d+(?:\.\d+)?) (?:deg|mm)"  # Signal.describe()
_SIGNAL = re.compile(_SIGNAL_TEXT + r" -> ([^;\n]*)")
_CAMERA_THEN = re.compile(r'^Your camera perception then: (".*")\s*$', re.MULTILINE)
_PLAN_THEN = re.compile(r'^Your plan then: (".*")\s*$', re.MULTILINE)
_SEARCH_SIDE = re.compile(r"search(?:ing)? to the (left|right)|turn (left|right) to search")
_LIMIT_DISTANCE = re.compile(r"0 < distance < (\d+(?:\.\d+)?) mm")
_LIMIT_ANGLE = re.compile(r"0 < angle < (\d+(?:\.\d+)?) degrees")
_LIMIT_SIGNALS = re.compile(r"[Aa]t most (\d+) (?:control signals|per answer)")


@dataclass(frozen=True)
class PastSignal:
    """One executed signal of R_{i-1} as the reference state text states it."""

    command: str
    direction: str
    value: float
    result: str

    @property
    def signed_turn_deg(self) -> float:
        if self.command != "turn":
            return 0.0
        return self.value if self.direction == "left" else -self.value


@dataclass(frozen=True)
class ReferenceReading:
    """R_{i-1} as the prompt states it: what was executed, where the can was seen, which way it searched."""

    step: int
    executed: tuple[PastSignal, ...] = ()
    sighting: TargetSighting | None = None
    search_side: str | None = None  # "left"/"right" when the plan then said which way it searched


@dataclass
class PromptReading:
    """The prompt, read: perception results, instruction, defences present, history, limits."""

    instruction: InstructionReading
    has_prefix: bool
    sighting: TargetSighting | None = None
    clearance: dict[str, float] | None = None
    points: np.ndarray | None = None
    reference: ReferenceReading | None = None
    refusals: list[Refusal] = field(default_factory=list)  # the failures section, as data
    refusals_left_out: int = 0  # earlier refusals the prompt left out
    max_distance_mm: float = 400.0
    max_angle_deg: float = 90.0
    max_signals: int = 5
    camera_aspect: float = 0.75  # image height / width

    def free_along(self, heading_deg: float, half_width_mm: float,
                   except_near: tuple[float, float, float] | None = None) -> float:
        """How far (mm) the robot could drive along ``heading_deg`` before a return enters its
        corridor of ``half_width_mm`` either side; with only sector text, that sector's clearance.
        ``except_near`` = (x, y, radius) ignores the returns of one known object (the can)."""
        if self.points is None:
            return self.range_towards(heading_deg, 22.5)
        points = self.points
        if except_near is not None and points.size:
            x, y, radius = except_near
            points = points[np.hypot(points[:, 0] - x, points[:, 1] - y) > radius]
        if points.size == 0:
            return math.inf
        rad = math.radians(heading_deg)
        along = points[:, 0] * math.cos(rad) + points[:, 1] * math.sin(rad)
        across = -points[:, 0] * math.sin(rad) + points[:, 1] * math.cos(rad)
        inside = (along > 0) & (np.abs(across) <= half_width_mm)
        return float(along[inside].min()) if inside.any() else math.inf

    def range_towards(self, bearing_deg: float, half_width_deg: float) -> float:
        """Nearest return (mm) within ``half_width_deg`` of ``bearing_deg``; nan when unknown."""
        if self.points is not None:
            return nearest_in_cone(self.points, bearing_deg, half_width_deg)
        if self.clearance is None:
            return math.nan
        index = int(round((bearing_deg % 360.0) / 45.0)) % len(SECTORS)
        return self.clearance[SECTORS[index]]

    def _latest(self) -> list[Refusal]:
        """The refusals of the latest attempt (a refusal that names no attempt counts as the latest)."""
        numbered = [r.attempt for r in self.refusals if r.attempt is not None]
        latest = max(numbered, default=None)
        return [r for r in self.refusals if r.attempt in (latest, None)]

    @property
    def asked_to_wait(self) -> bool:
        """Did a refusal of the latest attempt ask to wait for something moving to pass?"""
        return any(r.advice is not None and r.advice.wait for r in self._latest())

    @property
    def step_aside(self) -> list[dict] | None:
        """The step aside a refusal of the latest attempt advised (the plan, as signals), if any."""
        for refusal in self._latest():
            if refusal.advice is not None and refusal.advice.step_aside:
                return [_signal(step) for step in refusal.advice.step_aside]
        return None

    @property
    def amendment(self) -> tuple[list[dict], dict[int, float]] | None:
        """The latest attempt's refused plan and, per signal (0-based), the longest straight the
        refusals said is safe (0: none; a wait for a mover to pass), when every refusal of that
        attempt named its signal and said how far is safe; else None (nothing to amend by)."""
        if not self.refusals or self.refusals[-1].attempt is None:
            return None
        latest = self._latest()
        if self.refusals_left_out and self.refusals[0] is latest[0]:
            return None  # the prompt may have left out some of the latest attempt's refusals
        plan: list[dict] | None = None
        safe: dict[int, float] = {}
        for refusal in latest:
            advice, index = refusal.advice, refusal.signal_index
            if not refusal.plan or index is None or advice is None or advice.safe_mm is None:
                return None
            plan = [_signal(signal) for signal in refusal.plan]
            if not 0 <= index < len(plan) or plan[index]["command"] != "straight":
                return None
            safe[index] = min(safe.get(index, math.inf), advice.safe_mm)
        return (plan, safe) if plan is not None else None

    @property
    def safe_distance_hint_mm(self) -> float | None:
        """The smallest safe distance a validator reported on an earlier attempt."""
        values = [r.advice.safe_mm for r in self.refusals if r.advice is not None and r.advice.safe_mm is not None]
        return min(values) if values else None


def _signal(signal: ControlSignal) -> dict:
    """A signal as the pilot plans with it: command, direction, value (mm or degrees)."""
    value = signal.distance if isinstance(signal, Straight) else signal.angle
    return {"command": signal.command, "direction": signal.direction, "value": float(value)}


def _instruction(text: str) -> str:
    fenced = _FENCED.search(text)
    if fenced is not None:
        return fenced.group(3)
    match = _INSTRUCTION.search(text)
    if match is None:
        return text
    try:
        value = json.loads(match.group(1))
    except json.JSONDecodeError:
        return match.group(1)
    return value if isinstance(value, str) else match.group(1)


def _reference(text: str) -> ReferenceReading | None:
    match = _REFERENCE.search(text)
    if match is None:
        return None
    executed = tuple(PastSignal(c, d, float(v), r.strip().rstrip("."))
                     for c, d, v, r in _SIGNAL.findall(match.group(2)))
    sighting = None
    then = _CAMERA_THEN.search(text)
    if then is not None:
        try:
            sighting = parse_target_text(json.loads(then.group(1)))
        except json.JSONDecodeError:
            sighting = None
    side = None
    plan = _PLAN_THEN.search(text)
    if plan is not None:
        found = _SEARCH_SIDE.search(plan.group(1))
        side = (found.group(1) or found.group(2)) if found else None
    return ReferenceReading(step=int(match.group(1)), executed=executed, sighting=sighting, search_side=side)


def read_prompt(prompt: Prompt, camera_fov_deg: float = 60.0, lidar_range_mm: float = 4000.0) -> PromptReading:
    """Read ``prompt`` the way the mock pilot does (see the module docstring)."""
    text = prompt.user_text
    lines = _FENCED.sub("", text).splitlines()
    reading = PromptReading(
        instruction=read_instruction(_instruction(text)),
        has_prefix="security_prefix" in prompt.sections,
        reference=_reference(text) if "reference_state" in prompt.sections else None,
        refusals=list(prompt.refusals),
        refusals_left_out=prompt.refusals_left_out,
    )
    for pattern, name, kind in ((_LIMIT_DISTANCE, "max_distance_mm", float), (_LIMIT_ANGLE, "max_angle_deg", float),
                                (_LIMIT_SIGNALS, "max_signals", int)):
        match = pattern.search(prompt.system)
        if match:
            setattr(reading, name, kind(match.group(1)))
    for image in prompt.images:
        if image.name == "camera_image":
            pixels = decode_png(image.data)
            reading.sighting = find_red_target(pixels, camera_fov_deg)
            reading.camera_aspect = pixels.shape[0] / pixels.shape[1]
        elif image.name == "lidar_image":
            picture = read_lidar_image(image.data, lidar_range_mm)
            reading.points = picture.points_mm
            reading.clearance = sector_clearance_from_points(picture.points_mm)
    for line in lines:
        if reading.sighting is None and line.startswith("Camera:"):
            reading.sighting = parse_target_text(line)
        elif reading.clearance is None and line.startswith("LiDAR nearest obstacle:"):
            reading.clearance = parse_lidar_text(line)
    return reading
