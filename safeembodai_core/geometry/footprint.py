"""The robot's body as a region of the plane: a disc or a simple polygon, grown by a margin.

A :class:`Body` is in the robot frame (millimetres, x forward, y left, origin at the robot's centre,
the point it turns about). Grown by ``margin_mm`` it is the Minkowski sum of the shape and a disc of
that radius -- every point within the margin of the shape -- which is exactly

* a disc of radius ``radius + margin`` for a disc, and
* for a polygon, the polygon, plus a band along each edge (the edge moved outwards by the margin),
  plus a disc of the margin's radius at each vertex.

:meth:`Body.boundary` gives the pieces whose crossing is the first touch of a moving point
(:mod:`safeembodai_core.geometry.sweep`): the polygon's edges, the edges moved outwards, the vertex
discs. A point that starts outside the grown body first touches it where it first crosses one of
them, so no piece needs to be clipped to the outline. :meth:`Body.depth` says how deep a point lies
(the margin plus its signed distance to the shape), and :meth:`Body.level_pieces` where the points of
a given depth lie, for a point the body already holds. :func:`read_polygon` reads a footprint
strictly: finite vertices, at least three, not self-intersecting, of non-zero area; a bad one is a
``ValueError`` naming the field.
"""

from __future__ import annotations

import math
import reprlib
from dataclasses import dataclass
from typing import Any, Sequence

import numpy as np

#: Most vertices a footprint may have (a finer outline is no robot's, and costs every check).
MAX_VERTICES = 64
#: The farthest a vertex may lie from the robot's centre (100 m): no robot's, and squares stay finite.
MAX_COORDINATE_MM = 100_000.0
_AREA_EPS_MM2 = 1e-6


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _millimetres(value: Any) -> float:
    """``value`` as a float; NaN, which the caller refuses by name, when it is none (an integer too large)."""
    try:
        return float(value)
    except (TypeError, ValueError, OverflowError):
        return math.nan


def _shown(value: Any) -> str:
    """``value`` for an error message, short (a huge integer cut)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 64:
        return f"an integer of {value.bit_length()} bits"
    try:
        return reprlib.repr(value)
    except ValueError:  # an integer past Python's digit limit
        return f"a {type(value).__name__}"


def _segments_cross(p1: np.ndarray, p2: np.ndarray, q1: np.ndarray, q2: np.ndarray) -> bool:
    """True when the closed segments p1-p2 and q1-q2 share a point."""
    d1, d2 = p2 - p1, q2 - q1
    denom = float(_cross(d1, d2))
    if abs(denom) < 1e-12:  # parallel: they share a point only when collinear and overlapping
        if abs(float(_cross(q1 - p1, d1))) > 1e-9:
            return False
        length2 = float(d1 @ d1)
        s0, s1 = sorted((float((q1 - p1) @ d1) / length2, float((q2 - p1) @ d1) / length2))
        return s1 >= 0.0 and s0 <= 1.0
    t = float(_cross(q1 - p1, d2)) / denom
    u = float(_cross(q1 - p1, d1)) / denom
    return -1e-12 <= t <= 1 + 1e-12 and -1e-12 <= u <= 1 + 1e-12


def read_polygon(vertices: Any, field: str = "footprint_mm") -> np.ndarray:
    """``vertices`` as a counter-clockwise (V, 2) array of a simple polygon, or a ``ValueError``
    naming ``field``: at least three finite ``(x, y)`` pairs, no two edges crossing or touching
    except neighbours at their shared vertex, an area above zero."""
    try:
        points = np.array(vertices, dtype=float)
    except (TypeError, ValueError, OverflowError):  # an integer too large for a float too
        raise ValueError(f"{field} must be a list of (x, y) pairs in mm, got {_shown(vertices)}") from None
    if points.ndim != 2 or points.shape[1] != 2 or not 3 <= len(points) <= MAX_VERTICES:
        raise ValueError(f"{field} must be 3 to {MAX_VERTICES} (x, y) pairs in mm, got shape {points.shape}")
    if not np.isfinite(points).all():
        bad = int(np.flatnonzero(~np.isfinite(points).all(axis=1))[0])
        raise ValueError(f"{field}[{bad}] must be finite, got ({float(points[bad][0])}, {float(points[bad][1])})")
    if np.abs(points).max() > MAX_COORDINATE_MM:
        bad = int(np.flatnonzero(np.abs(points).max(axis=1) > MAX_COORDINATE_MM)[0])
        raise ValueError(f"{field}[{bad}] lies more than {MAX_COORDINATE_MM:.0f} mm from the centre: "
                         f"({float(points[bad][0])}, {float(points[bad][1])})")
    n = len(points)
    for i in range(n):
        a, b = points[i], points[(i + 1) % n]
        if float(np.hypot(*(b - a))) == 0.0:
            raise ValueError(f"{field}[{i}] and [{(i + 1) % n}] are the same vertex")
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # the first and last edges share vertex 0
            if _segments_cross(a, b, points[j], points[(j + 1) % n]):
                raise ValueError(f"{field} is not a simple polygon: edge {i} crosses edge {j}")
    area = 0.5 * float(np.sum(_cross(points, np.roll(points, -1, axis=0))))
    if abs(area) <= _AREA_EPS_MM2:
        raise ValueError(f"{field} encloses no area (its vertices are collinear)")
    return points if area > 0 else points[::-1].copy()


@dataclass(frozen=True)
class Body:
    """The robot's body grown by ``margin_mm`` (module docstring): a disc (``polygon`` None) or
    a counter-clockwise simple polygon."""

    radius_mm: float
    polygon: np.ndarray | None = None
    margin_mm: float = 0.0

    @classmethod
    def of(cls, radius_mm: float, footprint_mm: Sequence[Sequence[float]] | None, margin_mm: float = 0.0) -> "Body":
        """The body of a robot of ``radius_mm`` (used when ``footprint_mm`` is None) grown by ``margin_mm``."""
        margin = _millimetres(margin_mm)
        if not math.isfinite(margin) or margin < 0:
            raise ValueError(f"margin_mm must be a finite number of mm >= 0, got {_shown(margin_mm)}")
        if footprint_mm is None:
            radius = _millimetres(radius_mm)
            if not math.isfinite(radius) or radius <= 0:
                raise ValueError(f"radius_mm must be a finite number of mm > 0, got {_shown(radius_mm)}")
            return cls(radius, None, margin)
        polygon = read_polygon(footprint_mm)
        return cls(float(np.max(np.hypot(polygon[:, 0], polygon[:, 1]))), polygon, margin)

    @property
    def reach_mm(self) -> float:
        """The farthest any point of the grown body lies from the robot's centre."""
        return self.radius_mm + self.margin_mm

    def inside(self, points: np.ndarray) -> np.ndarray:
        """Per (N, 2) point: inside the grown body or on its edge, as it stands now."""
        if self.polygon is None:
            return np.hypot(points[:, 0], points[:, 1]) <= self.reach_mm
        inside = in_polygon(points, self.polygon)
        if self.margin_mm > 0:
            inside |= _distance_to_edges(points, self.polygon) <= self.margin_mm
        return inside

    def depth(self, points: np.ndarray) -> np.ndarray:
        """Per (N, 2) point: how deep it lies in the grown body (mm) -- the margin plus its signed
        distance to the shape (positive inside): 0 on the grown body's outline, negative outside.
        For a disc, the distance to the outline; a point is :meth:`inside` where this is >= 0."""
        if self.polygon is None:
            return self.reach_mm - np.hypot(points[:, 0], points[:, 1])
        distance = _distance_to_edges(points, self.polygon)
        return self.margin_mm + np.where(in_polygon(points, self.polygon), distance, -distance)

    def level_pieces(self, depths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Per depth (N,): pieces holding every point of the plane that lies that deep in the body
        (:meth:`depth`), as (N, S, 2, 2) segments and (N, C, 3) circles: the disc's circle through
        them, or the polygon's edges moved inwards by the depth less the margin (outwards when that
        is negative) and circles of that radius about its vertices. Only points on a piece can be
        exactly that deep; a piece may hold points that are not."""
        shape_depth = np.asarray(depths, dtype=float) - self.margin_mm  # the signed distance to the shape
        if self.polygon is None:
            radius = self.radius_mm - shape_depth
            return np.empty((len(radius), 0, 2, 2)), np.stack(
                (np.zeros_like(radius), np.zeros_like(radius), radius), axis=1)[:, None, :]
        start, end = self.polygon, np.roll(self.polygon, -1, axis=0)
        edge = end - start
        inward = np.column_stack((-edge[:, 1], edge[:, 0])) / np.hypot(edge[:, 0], edge[:, 1])[:, None]
        shift = shape_depth[:, None, None] * inward[None]  # counter-clockwise polygon: (-dy, dx) points inwards
        segments = np.stack((start[None] + shift, end[None] + shift), axis=2)
        radius = np.broadcast_to(np.abs(shape_depth)[:, None], (len(shape_depth), len(start)))
        circles = np.concatenate((np.broadcast_to(start, (len(shape_depth),) + start.shape), radius[..., None]), axis=2)
        return segments, circles

    def boundary(self) -> tuple[np.ndarray, np.ndarray]:
        """The pieces a moving point crosses first (module docstring): segments as (S, 2, 2)
        and circles as (C, 3) rows of centre x, y and radius."""
        if self.polygon is None:
            return np.empty((0, 2, 2)), np.array([[0.0, 0.0, self.reach_mm]])
        start, end = self.polygon, np.roll(self.polygon, -1, axis=0)
        segments = [np.stack((start, end), axis=1)]
        if self.margin_mm == 0:
            return segments[0], np.empty((0, 3))
        edge = end - start
        outward = np.column_stack((edge[:, 1], -edge[:, 0])) / np.hypot(edge[:, 0], edge[:, 1])[:, None]
        shift = outward * self.margin_mm  # counter-clockwise polygon: (dy, -dx) points outwards
        segments.append(np.stack((start + shift, end + shift), axis=1))
        circles = np.column_stack((self.polygon, np.full(len(self.polygon), self.margin_mm)))
        return np.concatenate(segments), circles

    def describe(self) -> str:
        shape = (f"a disc of radius {self.radius_mm:g} mm" if self.polygon is None
                 else f"a {len(self.polygon)}-vertex footprint")
        return shape + (f" + {self.margin_mm:g} mm margin" if self.margin_mm else "")


def in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule, with a point on an edge (to 1e-9 mm) counted inside; the edge distance is
    worked out only for the few points the rule left outside within the polygon's box."""
    x, y = points[:, 0:1], points[:, 1:2]
    a, b = polygon[None, :, :], np.roll(polygon, -1, axis=0)[None, :, :]
    straddles = (a[..., 1] > y) != (b[..., 1] > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[..., 0] + (y - a[..., 1]) * (b[..., 0] - a[..., 0]) / (b[..., 1] - a[..., 1])
    inside = (np.count_nonzero(straddles & (x < x_cross), axis=1) % 2) == 1
    low, high = polygon.min(axis=0) - 1e-9, polygon.max(axis=0) + 1e-9
    edge = np.flatnonzero(~inside & np.all((points >= low) & (points <= high), axis=1))
    if edge.size:
        inside[edge] = _distance_to_edges(points[edge], polygon) <= 1e-9
    return inside


def _distance_to_edges(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Per point, its distance to the polygon's outline."""
    a = polygon[None, :, :]
    edge = np.roll(polygon, -1, axis=0)[None, :, :] - a
    rel = points[:, None, :] - a
    t = np.clip(np.sum(rel * edge, axis=2) / np.sum(edge * edge, axis=2), 0.0, 1.0)
    nearest = rel - t[..., None] * edge
    return np.min(np.hypot(nearest[..., 0], nearest[..., 1]), axis=1)


__all__ = ["MAX_VERTICES", "Body", "in_polygon", "read_polygon"]
