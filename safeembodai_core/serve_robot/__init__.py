"""A scenario's room served as a rosbridge v2 robot (``safeembodai serve-robot``).

:mod:`.session` checks and starts a session, :mod:`.served_room` runs the room on the wall clock
(held velocity commands in, sensors out), :mod:`.messages` writes the room's readings as ROS 2
messages in rosbridge's JSON, and :mod:`.session_record` keeps the session as a run folder that
``show``, ``report`` and ``view`` read. The wire itself is :mod:`safeembodai_core.rosbridge`'s.
"""
