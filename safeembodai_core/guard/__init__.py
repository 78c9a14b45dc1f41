"""The Guard: judging a robot's commands against its sensors, whatever sends them.

``guard.Guard`` (the library's entry point: plans, LLM answers, held velocities), what it answers
(``reports``), how a held twist is judged, refused or limited (``twist_judging``, ``held_motion``), and
its front ends that take ROS messages: the command filter of ``guard-node`` and ``guard-mcp``
(``command_filter``) and the recorded-bag audit of ``guard-bag`` (``bag_guard``). The rules themselves
are validator plugins; the message types live in ``safeembodai_core.ros``.
"""
