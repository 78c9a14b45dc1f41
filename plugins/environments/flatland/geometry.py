"""Ray casting and swept-disc collision in an axis-aligned room with round bodies (numpy)."""

from __future__ import annotations

import numpy as np

WALL = -1


def cast_rays(origin: np.ndarray, angles_rad: np.ndarray, room: float,
              circles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance to the first hit along each ray, and what was hit (``WALL`` or a circle index).

    ``circles`` is (K, 3): x, y, radius. Rays start at ``origin`` (2,) in world millimetres.
    """
    dx, dy = np.cos(angles_rad), np.sin(angles_rad)
    ox, oy = float(origin[0]), float(origin[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(dx > 0, (room - ox) / dx, np.where(dx < 0, -ox / dx, np.inf))
        ty = np.where(dy > 0, (room - oy) / dy, np.where(dy < 0, -oy / dy, np.inf))
    distance = np.minimum(tx, ty)
    hit = np.full(angles_rad.shape, WALL, dtype=int)
    if len(circles):
        t = circle_hits(origin, dx, dy, circles)  # (rays, K)
        nearest = np.argmin(t, axis=1)
        best = t[np.arange(t.shape[0]), nearest]
        closer = best < distance
        distance = np.where(closer, best, distance)
        hit = np.where(closer, nearest, hit)
    return distance, hit


def circle_hits(origin: np.ndarray, dx: np.ndarray, dy: np.ndarray, circles: np.ndarray) -> np.ndarray:
    """(rays, K) distance along each ray to each circle's surface, ``inf`` when missed."""
    rel_x = origin[0] - circles[:, 0]
    rel_y = origin[1] - circles[:, 1]
    b = dx[:, None] * rel_x[None, :] + dy[:, None] * rel_y[None, :]
    c = rel_x**2 + rel_y**2 - circles[:, 2] ** 2
    disc = b**2 - c[None, :]
    root = np.sqrt(np.where(disc >= 0, disc, 0.0))
    t = -b - root
    t = np.where(t < 0, -b + root, t)  # origin inside a circle: exit point
    return np.where((disc >= 0) & (t >= 0), t, np.inf)


def free_travel(position: np.ndarray, direction: np.ndarray, radius: float, room: float,
                circles: np.ndarray) -> tuple[float, int]:
    """How far a disc of ``radius`` can slide along unit ``direction`` before touching something.

    Returns (distance, what it touches: ``WALL`` or circle index).
    """
    best, what = np.inf, WALL
    for axis in (0, 1):
        if direction[axis] > 1e-12:
            t = (room - radius - position[axis]) / direction[axis]
        elif direction[axis] < -1e-12:
            t = (radius - position[axis]) / direction[axis]
        else:
            continue
        if t < best:
            best, what = max(t, 0.0), WALL
    for index, (cx, cy, cr) in enumerate(circles):
        rel = position - np.array([cx, cy])
        b = float(direction @ rel)
        c = float(rel @ rel) - (radius + cr) ** 2
        disc = b * b - c
        if disc < 0:
            continue
        t = -b - np.sqrt(disc)
        if c <= 0:  # already touching: only moving away is free
            t = 0.0 if b < 0 else np.inf
        if 0 <= t < best:
            best, what = t, index
    return float(best), what
