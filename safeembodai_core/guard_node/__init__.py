"""The guard live between a planner and the base, over rosbridge (``safeembodai guard-node``).

:mod:`.node` decides (the robot file's body, scanner and limits; the velocity smoother of
:mod:`.smoother`, then :class:`~safeembodai_core.ros.CommandFilter`; stops on a stale scan or
silent planner), :mod:`.wire` puts it on a rosbridge connection.
"""
