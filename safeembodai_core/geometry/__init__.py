"""Plane geometry of the robot's body: its footprint (:mod:`.footprint`) and the exact time a held
velocity first brings it onto a point (:mod:`.sweep`). No numpy-free fallback, no simulator."""

from .footprint import MAX_VERTICES, Body, in_polygon, read_polygon
from .frames import relative_pose, wrap_deg
from .sweep import Motion, contact_times

__all__ = ["MAX_VERTICES", "Body", "Motion", "contact_times", "in_polygon", "read_polygon", "relative_pose", "wrap_deg"]
