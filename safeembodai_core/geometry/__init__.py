"""Plane geometry of the robot's body: its footprint (:mod:`.footprint`) and the exact time a held
velocity first brings it onto a point (:mod:`.sweep`). No numpy-free fallback, no simulator."""

from .footprint import MAX_VERTICES, Body, in_polygon, read_polygon
from .frames import advance, compose, into_frame, out_of_frame, relative_pose, wrap_deg
from .sweep import Motion, contact_times

__all__ = ["MAX_VERTICES", "Body", "Motion", "advance", "compose", "contact_times", "in_polygon", "into_frame",
           "out_of_frame", "read_polygon", "relative_pose", "wrap_deg"]
