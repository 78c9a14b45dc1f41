"""Where a mover cannot go: what the scan shows standing, so that predicted courses turn there.

Without it a mover's predicted courses (:mod:`.futures`) pass through walls: a mover heading for a
wall is predicted beyond it, away from the robot, while a real one -- a person, a cart, a robot --
turns and comes back into the room. :class:`Walls` keeps the returns of the step's scan that
belong to no mover (walls, furniture, balls: the room as the robot sees it now) on a grid of
:data:`CELL_MM` cells. A course whose next position would bring the mover's disc onto a cell
holding a return turns instead: the rule is not told how movers turn, so the new heading is drawn
evenly among :data:`HEADINGS` headings whose next position is free (none free: the course stands
for that moment). Only what the scan saw counts: a wall hidden behind a mover, or out of range, is
not there for the courses, as before.
"""

from __future__ import annotations

import math

import numpy as np

from safeembodai_core.models import LidarScan, Pose

from .tracking import Blob, _returns, _to_room

#: Side of a grid cell (mm): a return marks its cell, a disc is blocked by the cells it may touch.
CELL_MM = 50.0
#: Headings tried, evenly round, when a course meets a wall.
HEADINGS = 16
#: A return this close (mm) beyond a mover's disc belongs to the mover, not to the room.
OWN_SLACK_MM = 100.0
#: Returns farther than this (mm), or than the scan's range, are not walls: the grid stays bounded
#: (at most 800 x 800 cells) whatever a hostile scan reports.
REACH_MM = 20_000.0


class Walls:
    """The scan's standing returns in the room frame, as a grid of occupied cells."""

    def __init__(self, points: np.ndarray, cell_mm: float = CELL_MM) -> None:
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        self.cell = float(cell_mm)
        self.count = len(points)
        self._blocked: dict[int, np.ndarray] = {}
        if not len(points):
            self.origin, self.occupied = np.zeros(2), np.zeros((0, 0), dtype=bool)
            return
        self.origin = np.floor(points.min(axis=0) / self.cell) * self.cell
        cells = np.floor((points - self.origin) / self.cell).astype(int)
        shape = cells.max(axis=0) + 1
        self.occupied = np.zeros((int(shape[0]), int(shape[1])), dtype=bool)
        self.occupied[cells[:, 0], cells[:, 1]] = True

    @classmethod
    def seen(cls, scan: LidarScan, pose: Pose, movers: list[Blob]) -> "Walls":
        """The returns of ``scan`` (taken at ``pose``) within its range (and :data:`REACH_MM`) that
        lie on none of ``movers``' discs."""
        _, points = _returns(scan)
        points = points[np.hypot(points[:, 0], points[:, 1]) <= min(float(scan.max_range_mm), REACH_MM)]
        room = _to_room(points, pose) if len(points) else np.zeros((0, 2))
        keep = np.ones(len(room), dtype=bool)
        for blob in movers:
            keep &= np.hypot(*(room - blob.centre).T) > blob.radius_mm + OWN_SLACK_MM
        return cls(room[keep])

    def _mask(self, radius_mm: float) -> tuple[np.ndarray, int]:
        """Cells a disc of ``radius_mm`` centred in them may touch a return from (a square bound),
        and the padding k of that mask: cell (i, j) of the grid is ``mask[i + k, j + k]``."""
        k = int(math.ceil(radius_mm / self.cell))
        mask = self._blocked.get(k)
        if mask is None:  # a box filter over the grid padded by 2k
            total = np.pad(np.cumsum(np.cumsum(np.pad(self.occupied, 2 * k), axis=0), axis=1), ((1, 0), (1, 0)))
            w = 2 * k + 1
            mask = (total[w:, w:] - total[:-w, w:] - total[w:, :-w] + total[:-w, :-w]) > 0
            self._blocked[k] = mask
        return mask, k

    def blocked(self, xy: np.ndarray, radius_mm: float) -> np.ndarray:
        """Per point of ``xy`` (..., 2): would a disc of ``radius_mm`` there touch a standing
        return? Outside the scan's returns nothing blocks."""
        xy = np.asarray(xy, dtype=float)
        if not self.count:
            return np.zeros(xy.shape[:-1], dtype=bool)
        mask, k = self._mask(radius_mm)
        cell = np.floor((xy - self.origin) / self.cell).astype(int) + k
        inside = (cell[..., 0] >= 0) & (cell[..., 1] >= 0) & (cell[..., 0] < mask.shape[0]) \
            & (cell[..., 1] < mask.shape[1])
        out = np.zeros(xy.shape[:-1], dtype=bool)
        out[inside] = mask[cell[..., 0][inside], cell[..., 1][inside]]
        return out
