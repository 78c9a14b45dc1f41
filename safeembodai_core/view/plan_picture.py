"""A step's plans drawn where they would have gone: a static SVG for the trial page (no script).

In the robot's frame at the step's scan, heading up: the scan's returns (blue dots), the robot's
body (a circle), and each attempt's plan as the path it would drive (accepted green, refused red;
an answer that did not parse has none), with, for a refused straight, the nearest return in its
corridor (the body's width) from its start on circled in red and the refusing rule named in the
attempt's tooltip. Numbers are ours; every name from data (rule names) is XML-escaped.
"""

from __future__ import annotations

from html import escape
from typing import Any

import numpy as np

from ..geometry.plans import nearest_ahead, plan_path
from ..models import Pose, Straight
from ..models.observation import LidarScan

GREEN, RED, BLUE, GREY = "#28be46", "#dc2828", "#5aa0ff", "#888888"
SIZE_PX = 360


def plan_svg(scan: LidarScan | None, attempts: list[Any], robot_radius_mm: float) -> str:
    """The SVG text of one step (module docstring); ``attempts`` are the step's recorded attempts."""
    origin = Pose(x_mm=0.0, y_mm=0.0, heading_deg=0.0)
    points = scan.points() if scan is not None else np.zeros((0, 2))
    paths = []
    reach = 1500.0
    for attempt in attempts:
        if attempt.response is None:
            continue
        path, segments = plan_path(origin, list(attempt.response.control))
        reach = max(reach, float(np.abs(path).max()) + 300.0)
        blocked = []
        for verdict in attempt.verdicts:
            index = verdict.signal_index
            if verdict.valid or index is None or not 0 <= index < len(segments):
                continue
            if isinstance(attempt.response.control[index], Straight):
                start, end = segments[index]
                found = nearest_ahead(points, start, end, robot_radius_mm)
                if found is not None:
                    blocked.append(found)
        refused_by = sorted({v.rule for v in attempt.verdicts if not v.valid})
        paths.append((attempt.index + 1, attempt.accepted, path, blocked, refused_by))
    if scan is not None:
        reach = min(max(reach, 2500.0), scan.max_range_mm)
    scale = SIZE_PX / (2 * reach)

    parts = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{SIZE_PX}" height="{SIZE_PX}" '
             f'viewBox="0 0 {SIZE_PX} {SIZE_PX}"><rect width="100%" height="100%" fill="#ffffff"/>']
    inside = points[np.abs(points).max(axis=1) <= reach] if points.size else points
    parts += [f'<circle cx="{x}" cy="{y}" r="1.5" fill="{BLUE}"/>' for x, y in _screen(inside, scale)]
    centre = SIZE_PX / 2
    parts.append(f'<circle cx="{centre}" cy="{centre}" r="{max(robot_radius_mm * scale, 2):.1f}" fill="none" '
                 f'stroke="{GREY}" stroke-width="1.5"/>')
    for number, accepted, path, blocked, refused_by in paths:
        colour = GREEN if accepted else RED
        title = f"attempt {number}: " + ("accepted" if accepted else "refused by " + ", ".join(refused_by or ["?"]))
        line = " ".join(f"{x},{y}" for x, y in _screen(path, scale))
        parts.append(f'<g><title>{escape(title)}</title><polyline points="{line}" fill="none" stroke="{colour}" '
                     f'stroke-width="2.5" stroke-opacity="0.8"/>')
        for x, y in _screen(np.array(blocked), scale):
            parts.append(f'<circle cx="{x}" cy="{y}" r="6" fill="none" stroke="{RED}" stroke-width="2"/>')
        parts.append("</g>")
    parts.append("</svg>")
    return "".join(parts)


def _screen(points: np.ndarray, scale: float) -> list[tuple[float, float]]:
    """``points`` (N, 2; robot frame: x ahead, y left) on the screen, heading up, to 0.1 px: all at
    once, the same arithmetic and rounding (numpy's, as a float64's ``round`` does) a point at a time
    would give, so the same text."""
    if not len(points):
        return []
    points = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    xs = np.round(SIZE_PX / 2 - points[:, 1] * scale, 1).tolist()
    ys = np.round(SIZE_PX / 2 - points[:, 0] * scale, 1).tolist()
    return list(zip(xs, ys))
