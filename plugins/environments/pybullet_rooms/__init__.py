"""``OF``/``SO``/``DO``/``MO``: the paper's four rooms on pybullet.

A mobile robot must find a red can in a square room and approach it. ``OF`` holds only the
walls, the robot and the can; ``SO`` adds static soccer balls; ``DO`` adds wandering Labbots;
``MO`` has both. Each environment runs its own pybullet client in DIRECT mode (no display),
moves the robot kinematically in small increments checked for contact, and reads a QVGA front
camera (TinyRenderer), a 360-beam LiDAR (one batched ray cast) and ground truth for metrics.
See ``docs/environments.md``.

This module only registers names and options: pybullet is imported by the factory.
"""

from __future__ import annotations

from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.plugin.registry import lazy

from .options import ROOMS


@hookimpl
def register_environments(register):
    for kind, (model, description) in ROOMS.items():
        register(kind, lazy(f"{__name__}.world", "PybulletRoom", kind), options=model, description=description)
