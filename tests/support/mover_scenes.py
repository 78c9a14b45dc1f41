"""Synthetic scenes for ``moving_obstacles``' tests: a square room with discs (Labbots, balls) scanned
from a pose, the commands a plan is made of, and the learned rule with the options its tests share.

Used by tests/plugins/validators/moving/ (the rule, its learning and its walls)."""

from __future__ import annotations

import numpy as np

from safeembodai_core.models import LidarScan, Pose, Straight, Turn
from safeembodai_core.validation.context import PastScan, ValidationContext, validate_plan
from safeembodai_plugins.validators import MovingObstaclesOptions
from safeembodai_plugins.validators.moving import MovingObstaclesRule

ROOM_MM = 6000.0
THINK_S = 5.0
LABBOT_MM = 120.0
#: where the robot stands in most scenes: 1 m from the left wall, half-way up, facing +x
ROBOT = Pose(x_mm=1000.0, y_mm=3000.0, heading_deg=0.0)
#: the learned rule's options its tests share (history, wander prior, futures, accepted risk)
LEARNING = {"history_scans": 4, "wander_deg": 45.0, "think_time_s": THINK_S, "futures": 256, "max_risk": 0.05}


def scan_from(pose: Pose, discs, beams: int = 360, max_range_mm: float = 8000.0) -> LidarScan:
    """Ranges from ``pose`` to the room's walls (a 0..ROOM_MM square) and to discs (x, y, radius)."""
    angles = np.radians(pose.heading_deg + np.arange(beams) * 360.0 / beams)
    ux, uy = np.cos(angles), np.sin(angles)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        tx = np.where(ux > 0, (ROOM_MM - pose.x_mm) / ux, np.where(ux < 0, -pose.x_mm / ux, np.inf))
        ty = np.where(uy > 0, (ROOM_MM - pose.y_mm) / uy, np.where(uy < 0, -pose.y_mm / uy, np.inf))
    ranges = np.minimum(tx, ty)
    for x, y, r in discs:
        dx, dy = x - pose.x_mm, y - pose.y_mm
        along = dx * ux + dy * uy
        across2 = dx * dx + dy * dy - along * along
        t = along - np.sqrt(np.maximum(r * r - across2, 0.0))
        ranges = np.where((along > 0) & (across2 <= r * r) & (t < ranges), t, ranges)
    return LidarScan(ranges_mm=np.where(ranges > max_range_mm, np.inf, ranges), max_range_mm=max_range_mm)


def go(distance: float) -> Straight:
    """A straight: forward for a positive distance (mm), backward for a negative one."""
    return Straight(command="straight", direction="forward" if distance > 0 else "backward", distance=abs(distance))


def rotate(angle: float) -> Turn:
    """A turn: left for a positive angle (degrees), right for a negative one."""
    return Turn(command="turn", direction="left" if angle > 0 else "right", angle=abs(angle))


def history_context(pose: Pose, positions: list[tuple[float, float]], dt_s: float = 6.0) -> ValidationContext:
    """The robot standing at ``pose`` for every scan; one Labbot at ``positions`` (oldest first), one
    scan each ``dt_s`` apart; the last is the step's scan."""
    scans = [PastScan(scan_from(pose, [(x, y, LABBOT_MM)]), pose, 10.0 + i * dt_s)
             for i, (x, y) in enumerate(positions)]
    now = scans[-1]
    return ValidationContext(scan=now.scan, start_pose=pose, sim_time_s=now.sim_time_s, history=tuple(scans[:-1]))


def learned_rule(**options) -> MovingObstaclesRule:
    """The rule with :data:`LEARNING`'s options, ``options`` on top."""
    return MovingObstaclesRule(MovingObstaclesOptions(**{**LEARNING, **options}))


def refused(plan, context, validator) -> list[str]:
    """The reasons ``validator`` (as ``moving_obstacles``) gives for refusing ``plan`` in ``context``."""
    return [v.reason for v in validate_plan(plan, context, [("moving_obstacles", validator)]) if not v.valid]
