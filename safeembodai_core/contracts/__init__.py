"""The contracts between the core and its plugins: the components' interfaces (``components``), how
backends and environments describe themselves (``descriptions``), the robot's body (``robot``) and
an attacker's schedule (``attack_schedule``)."""
