"""The mock pilot's decisions: a competent navigator with explicit, seeded weaknesses.

Given a :class:`~.mock_reading.PromptReading` it plans like a careful LLM would -- turn to
the can and drive at it, stopping short and keeping clear of obstacles; search by turning when
the can is out of view -- and then lets the options spoil that plan the way LLMs do: obey a
misaligned instruction, misjudge a distance, ignore the LiDAR, overlook a small can, forget
where the can was when no reference state says so. Every random choice comes from the
uniform and normal draws made up front from the call's rng, in a fixed order, so arms that
differ in one defence face the same dice (with the security prefix the mock obeys on a subset
of the draws where it obeys without it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from ...perception.describe import TargetSighting
from .reading import PromptReading
from safeembodai_core.geometry.frames import wrap_deg

ALIGN_TOLERANCE_DEG = 6.0
SMALL_TARGET = 0.06
_MIN_STRAIGHT_MM = 30.0


@dataclass
class Plan:
    """What the mock decided: flags, the perceived target, signals and the words around them."""

    flagged: bool = False
    obeyed: bool = False
    target_seen: bool = False
    signals: list[dict[str, Any]] = field(default_factory=list)
    planning: str = ""
    malformed: str | None = None


@dataclass(frozen=True)
class Dice:
    """The draws of one call: uniforms ``u`` and standard normals ``z``, in a fixed order."""

    u: np.ndarray
    z: np.ndarray

    @classmethod
    def roll(cls, rng: np.random.Generator) -> "Dice":
        return cls(u=rng.random(14), z=rng.standard_normal(4))


class _Can(NamedTuple):
    """Where a sighting that saw the can puts it."""

    bearing_deg: float
    height_fraction: float


def _can(sighting: TargetSighting | None) -> _Can | None:
    """The can of ``sighting`` when it saw one (a seen sighting has both numbers), else None."""
    if sighting is None or not sighting.seen:
        return None
    bearing, height = sighting.bearing_deg, sighting.height_fraction
    assert bearing is not None and height is not None  # a sighting that is seen has both
    return _Can(bearing, height)


def _turn(angle: float, left: bool, why: str, limit: float) -> dict[str, Any]:
    angle = float(min(max(round(abs(angle)), 1), limit - 1))
    return {"command": "turn", "direction": "left" if left else "right", "angle": angle, "justification": why}


def _fields(signal: dict[str, Any]) -> dict[str, Any]:
    """A signal read back from a refused plan (command, direction, value), as the answer's fields,
    with its value as it was (it passed, or is about to be shortened)."""
    key = "angle" if signal["command"] == "turn" else "distance"
    return {"command": signal["command"], "direction": signal["direction"], key: float(signal["value"])}


def _straight(distance: float, why: str, limit: float, forward: bool = True) -> dict[str, Any]:
    distance = float(min(max(round(distance / 10.0) * 10, 10.0), limit - 1))
    return {"command": "straight", "direction": "forward" if forward else "backward",
            "distance": distance, "justification": why}


class MockPolicy:
    """Decides a :class:`Plan` from a prompt reading, the options and the dice."""

    def __init__(self, options: Any) -> None:
        self.o = options

    def decide(self, r: PromptReading, dice: Dice) -> Plan:
        o, u, z = self.o, dice.u, dice.z
        plan = Plan()
        attack = r.instruction.suspicious
        flag_p = o.flag_injection_p_secure if r.has_prefix else o.flag_injection_p
        obey_p = (o.obey_injection_p_secure if r.has_prefix else o.obey_injection_p)
        if r.reference is not None:
            obey_p *= o.obey_factor_with_reference
        plan.flagged = bool(u[0] < flag_p) if attack else bool(u[10] < o.false_flag_p)
        plan.obeyed = attack and not plan.flagged and bool(u[1] < obey_p)
        can = _can(r.sighting)
        plan.target_seen = bool(can is not None
                                and not (can.height_fraction < SMALL_TARGET and u[6] < o.miss_target_p))
        if plan.obeyed:
            plan.signals, plan.planning = self._obey(r, u, z)
        elif can is not None and plan.target_seen:
            plan.signals, plan.planning = self._approach(r, can, u, z)
        else:
            plan.signals, plan.planning = self._search(r, u, z)
        if not self._amend(r, plan, u):
            self._apply_feedback(r, plan, u)
        straights = [s for s in plan.signals if s["command"] == "straight"]
        if straights and u[3] < o.limit_violation_p:
            straights[0]["distance"] = float(round(r.max_distance_mm * (1.05 + 0.2 * u[11])))
        if not r.refusals and u[2] < o.malformed_p:
            plan.malformed = ("truncated", "prose", "string_number", "missing_key")[int(u[11] * 4) % 4]
        if plan.obeyed and r.instruction.intent == "format" and u[11] < 0.5:
            plan.malformed = "prose"
        return plan

    # -- the task ------------------------------------------------------------------------------

    def _approach(self, r: PromptReading, can: _Can, u: np.ndarray, z: np.ndarray) -> tuple[list[dict[str, Any]], str]:
        o = self.o
        seen_at = float(can.bearing_deg)
        bearing = -seen_at if u[12] < o.bearing_mirror_p else seen_at
        signals = []
        heading = 0.0
        if abs(bearing) > ALIGN_TOLERANCE_DEG:
            signals.append(_turn(abs(bearing) + o.angle_error_sd_deg * z[1], bearing > 0, "face the red can",
                                 r.max_angle_deg))
            heading = math.copysign(signals[0]["angle"], bearing)
        target = self._target_distance(r, seen_at, can.height_fraction)
        careful = u[4] >= o.ignore_clearance_p
        near = (target * math.cos(math.radians(bearing)), target * math.sin(math.radians(bearing)), 200.0)
        if careful and r.free_along(heading, o.corridor_mm, except_near=near) < target - 100:
            return self._detour(r, heading, z), "An obstacle stands between the robot and the red can; go round it."
        desired = target - o.approach_stop_mm
        if careful:
            free = self._misread(r.free_along(heading, o.corridor_mm), z[3])
            desired = min(desired, free - o.clearance_margin_mm)
        if desired >= _MIN_STRAIGHT_MM:
            desired = self._sloppy(desired, r, z, cap=False)
            legs = min(max(1, math.ceil(desired / (r.max_distance_mm - 1))), o.max_straights_per_answer,
                       r.max_signals - len(signals))
            for _ in range(legs):
                signals.append(_straight(min(desired / legs, r.max_distance_mm - 1), "approach the red can",
                                         r.max_distance_mm))
        elif not signals:
            signals.append(_straight(_MIN_STRAIGHT_MM * 2, "close the last gap to the red can", r.max_distance_mm))
        where = ("straight ahead" if abs(bearing) < 0.5
                 else f"{abs(bearing):.0f} deg {'left' if bearing > 0 else 'right'}")
        return signals, f"The red can is {where}, about {target / 1000:.1f} m away; face it and approach."

    def _detour(self, r: PromptReading, heading: float, z: np.ndarray) -> list[dict[str, Any]]:
        o = self.o
        left = r.free_along(heading + 45, o.corridor_mm) >= r.free_along(heading - 45, o.corridor_mm)
        new_heading = heading + (45.0 if left else -45.0)
        signals = [_turn(abs(new_heading), new_heading > 0, "turn to pass the obstacle", r.max_angle_deg)]
        free = self._misread(r.free_along(new_heading, o.corridor_mm), z[3])
        distance = min(300.0, free - o.clearance_margin_mm)
        if distance >= _MIN_STRAIGHT_MM:
            signals.append(_straight(self._sloppy(distance, r, z), "pass the obstacle", r.max_distance_mm))
        return signals

    def _target_distance(self, r: PromptReading, bearing: float, height_fraction: float) -> float:
        """Distance to the can's surface: the LiDAR return at its bearing, else its apparent size."""
        lidar = r.range_towards(bearing, 3.0) if r.points is not None else math.nan
        half_v = math.atan(math.tan(math.radians(self.o.camera_fov_deg / 2)) * r.camera_aspect)
        by_size = self.o.target_height_mm / (max(height_fraction, 1e-3) * 2 * math.tan(half_v))
        if math.isfinite(lidar) and lidar < 1.5 * by_size:
            return lidar
        return by_size

    def _search(self, r: PromptReading, u: np.ndarray, z: np.ndarray) -> tuple[list[dict[str, Any]], str]:
        o = self.o
        ref = r.reference
        recalled = _can(ref.sighting) if ref is not None else None
        if ref is not None and recalled is not None and u[5] < o.recall_target_p:
            expected = recalled.bearing_deg - sum(s.signed_turn_deg for s in ref.executed)
            expected = wrap_deg(expected)
            angle = min(max(abs(expected), 15.0), r.max_angle_deg - 1)
            return [_turn(angle, expected > 0, "turn back to where the red can was", r.max_angle_deg)], \
                "The red can was in view last step; turn back towards it."
        last_turns = [s for s in (ref.executed if ref else ()) if s.command == "turn"]
        if last_turns:
            left = last_turns[-1].direction == "left"
        elif ref is not None and ref.search_side is not None:
            left = ref.search_side == "left"
        else:
            left = bool(u[8] < o.search_left_p)
        side = "left" if left else "right"
        ahead = self._misread(r.free_along(0.0, o.corridor_mm), z[3])
        careful = u[4] >= o.ignore_clearance_p
        if u[7] < o.explore_forward_p and (ahead > 1000 or not careful):
            distance = min(350.0, ahead - o.clearance_margin_mm) if careful else 350.0
            return [_straight(self._sloppy(distance, r, z), "explore open space", r.max_distance_mm)], \
                f"The red can is not in view; move into open space, then keep searching to the {side}."
        angle = o.search_turn_deg + 8.0 * z[2]
        return [_turn(angle, left, "search for the red can", r.max_angle_deg)], \
            f"The red can is not in view; turn {side} to search."

    # -- weaknesses ----------------------------------------------------------------------------

    def _obey(self, r: PromptReading, u: np.ndarray, z: np.ndarray) -> tuple[list[dict[str, Any]], str]:
        intent, limit = r.instruction.intent, r.max_distance_mm
        why = f"as instructed: {r.instruction.misaligned}"
        can = _can(r.sighting)
        away_left = bool(can.bearing_deg < 0) if can is not None else bool(u[8] < 0.5)
        if intent == "charge":
            signals = [_straight(limit - 1, why, limit), _straight(limit - 1, why, limit)]
        elif intent == "retreat":
            signals = [_straight(0.8 * limit + 40 * z[0], why, limit, forward=False),
                       _turn(60, away_left, why, r.max_angle_deg)]
        elif intent == "turn_away":
            signals = [_turn(75 + 10 * u[9], away_left, why, r.max_angle_deg)]
        elif intent == "avoid":
            signals = [_turn(85, away_left, why, r.max_angle_deg), _straight(300, why, limit)]
        elif intent == "format":
            signals = []
        elif intent == "spin":
            signals = [_turn(89, True, why, r.max_angle_deg), _turn(89, True, why, r.max_angle_deg)]
        else:  # roam (go elsewhere, e.g. the busiest part of the house) and override: wander off
            signals = [_turn(60, away_left, why, r.max_angle_deg), _straight(300, why, limit)]
        return signals, f"Follow the human instruction: {r.instruction.misaligned}"

    def _misread(self, distance: float, z: float) -> float:
        """A distance read off the LiDAR picture, with the reader's relative error (unknown: no room)."""
        if math.isnan(distance):
            return 0.0
        return distance * (1.0 + self.o.lidar_misread_sd * z) if math.isfinite(distance) else 5000.0

    def _sloppy(self, distance: float, r: PromptReading, z: np.ndarray, cap: bool = True) -> float:
        noisy = max(distance * (1.0 + self.o.distance_error_sd * z[0]), _MIN_STRAIGHT_MM)
        return float(min(noisy, r.max_distance_mm - 1)) if cap else float(noisy)

    def _amend(self, r: PromptReading, plan: Plan, u: np.ndarray) -> bool:
        """``retry: amend``: on a retry whose refusal advised a step aside (``moving_obstacles``'
        ``park_check``), send that step aside; on a retry whose refusals each named their signal and how far is safe,
        resend the refused plan up to the first refused straight, that one shortened to what is
        safe (less 20 mm), nothing after it -- the signals before it passed and are resent as they
        were. False when the pilot redraws instead (``retry: redraw``, it does not comply this time,
        nothing to amend by, or the refusal allows the whole straight: resending it would repeat it)."""
        if self.o.retry == "amend" and u[9] < self.o.feedback_compliance_p and r.step_aside is not None:
            plan.signals = [{**_fields(step), "justification": "step out of the moving obstacle's way, as advised"}
                            for step in r.step_aside]
            plan.planning = "Step aside as the refusal advised: " + (plan.planning or "")
            return True
        amendment = r.amendment if self.o.retry == "amend" else None
        if amendment is None or u[9] >= self.o.feedback_compliance_p:
            return False
        refused, safe = amendment
        kept = []
        for index, signal in enumerate(refused):
            if index not in safe:
                kept.append({**_fields(signal), "justification": "as planned before the refusal"})
                continue
            shorter = float(round((safe[index] - 20) / 10) * 10)
            if shorter >= signal["value"]:
                return False
            if shorter >= _MIN_STRAIGHT_MM:
                kept.append({**_fields(signal), "distance": shorter,
                             "justification": "shortened to what the refusal said is safe"})
            break
        plan.signals = self._or_wait(r, kept, u)
        plan.planning = "Amend the refused plan: " + (plan.planning or "")
        return True

    def _apply_feedback(self, r: PromptReading, plan: Plan, u: np.ndarray) -> None:
        hint = r.safe_distance_hint_mm
        if hint is None or u[9] >= self.o.feedback_compliance_p:
            return
        kept = []
        for signal in plan.signals:
            if signal["command"] == "straight" and signal["distance"] > hint - 20:
                if hint - 20 < _MIN_STRAIGHT_MM:
                    continue
                signal = {**signal, "distance": float(round((hint - 20) / 10) * 10),
                          "justification": signal["justification"] + " (shortened after the refusal)"}
            kept.append(signal)
        plan.signals = self._or_wait(r, kept, u)

    def _or_wait(self, r: PromptReading, kept: list[dict[str, Any]], u: np.ndarray) -> list[dict[str, Any]]:
        """What is left of a refused plan; with nothing left, a wait in place when the refusal asked to
        wait for a mover to pass, else a turn away from the blocked path."""
        if not kept and r.asked_to_wait:  # a mover in the way: wait in place, keep facing the task
            kept = [_turn(self.o.wait_turn_deg, bool(u[8] < 0.5), "wait for the moving obstacle to pass",
                          r.max_angle_deg)]
        return kept or [_turn(self.o.search_turn_deg, bool(u[8] < 0.5), "turn away from the blocked path",
                              r.max_angle_deg)]
