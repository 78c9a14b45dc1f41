"""The velocity smoother's basics, as Nav2 places them before its collision monitor.

Nav2's ``velocity_smoother`` (``nav2_velocity_smoother``) bounds each axis of a command to
``[min_velocity, max_velocity]``, then its change since the last command sent to
``max_accel * dt`` when the speed grows on the same side of zero and ``-max_decel * dt`` otherwise
(``applyConstraints``; each axis on its own, Nav2's default ``scale_velocities: false``). Here the
"last command" is the one the guard last sent to the base -- after the guard's own limit or stop --
so a command after a guard stop accelerates from zero, as the base does. A stop the guard sends is
not smoothed: a hazard does not wait for a deceleration ramp (Nav2's collision monitor, after the
smoother, stops at once too).
"""

from __future__ import annotations

from ..ros.robot_file import VelocitySmoother
from ..ros.twist import Twist


def _constrain(current: float, wanted: float, accel: float, decel: float, dt: float) -> float:
    """Nav2's ``applyConstraints`` for one axis (``decel`` <= 0, as Nav2 writes it)."""
    change = wanted - current
    if abs(wanted) >= abs(current) and current * wanted >= 0:
        low, high = -accel * dt, accel * dt
    else:
        low, high = decel * dt, -decel * dt
    return current + min(max(change, low), high)


class Smoother:
    """Bounds velocities and accelerations of successive commands (module docstring); ``period_s``
    is the node's cycle, Nav2's ``1 / smoothing_frequency``: the most time one step's change is
    allowed for, so that a base standing for a while still ramps up over cycles."""

    def __init__(self, limits: VelocitySmoother, period_s: float) -> None:
        self.limits, self.period_s = limits, period_s
        self.sent = Twist(0.0, 0.0)
        self.sent_at: float | None = None

    def smooth(self, twist: Twist, time_s: float) -> Twist:
        """``twist`` within the velocity bounds and, since the last command sent, the acceleration bounds."""
        lim = self.limits
        wanted = (min(max(twist.linear_x, lim.min_velocity[0]), lim.max_velocity[0]),
                  min(max(twist.linear_y, lim.min_velocity[1]), lim.max_velocity[1]),
                  min(max(twist.angular_z, lim.min_velocity[2]), lim.max_velocity[2]))
        dt = self.period_s if self.sent_at is None else min(max(time_s - self.sent_at, 0.0), self.period_s)
        current = (self.sent.linear_x, self.sent.linear_y, self.sent.angular_z)
        x, y, z = (_constrain(c, w, a, d, dt) for c, w, a, d in zip(current, wanted, lim.max_accel, lim.max_decel))
        return Twist(x + 0.0, z + 0.0, y + 0.0)

    def sent_now(self, twist: Twist, time_s: float) -> None:
        """The command the base was just sent (the next one's acceleration is from it)."""
        self.sent, self.sent_at = twist, time_s
