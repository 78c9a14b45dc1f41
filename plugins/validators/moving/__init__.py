"""``moving_obstacles``: refuse a motion that drives into where a mover may be by then.

The rule is :class:`~.moving_obstacles.MovingObstaclesRule` (:mod:`.moving_obstacles`, where its
model and assumptions are written); it finds movers with :mod:`.tracking`, learns their cruising
speed and wander with :mod:`.learning`, draws their courses with :mod:`.futures` and turns them at
walls with :mod:`.walls`. The validators' plugin module registers it (``lazy``, by this package's
name), so this package only says where the rule's names live: every name below is importable from
here, as it was when the rule lived in this file.
"""

from __future__ import annotations

from .moving_obstacles import _WORSE_MM as _WORSE_MM
from .moving_obstacles import Meeting, MoversSeen, MovingObstaclesRule, Sweep, seen_from
from .moving_obstacles import _planned_pose as _planned_pose

__all__ = ["Meeting", "MoversSeen", "MovingObstaclesRule", "Sweep", "seen_from"]
