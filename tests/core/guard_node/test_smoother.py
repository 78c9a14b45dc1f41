"""The velocity smoother before the guard: Nav2's bounds on velocity and acceleration."""

from __future__ import annotations

import pytest

from safeembodai_core.guard_node.smoother import Smoother
from safeembodai_core.ros.robot_file import VelocitySmoother
from safeembodai_core.ros.twist import Twist

LIMITS = VelocitySmoother(max_velocity=(0.5, 0.0, 2.0), min_velocity=(-0.3, 0.0, -2.0), max_accel=(1.0, 0.0, 4.0),
                          max_decel=(-2.0, 0.0, -8.0))


def test_velocity_is_bounded_per_axis_and_speed_ramps_up_by_the_acceleration_limit():
    smoother = Smoother(LIMITS, period_s=0.05)
    out = []
    t = 0.0
    for _ in range(12):
        t += 0.05
        twist = smoother.smooth(Twist(2.0, 3.0), t)
        smoother.sent_now(twist, t)
        out.append(twist)
    assert [round(o.linear_x, 3) for o in out[:4]] == [0.05, 0.1, 0.15, 0.2]  # 1 m/s^2 over 50 ms cycles
    assert out[-1].linear_x == pytest.approx(0.5)  # then the velocity bound
    assert out[0].angular_z == pytest.approx(0.2) and out[-1].angular_z == pytest.approx(2.0)


def test_slowing_uses_the_deceleration_limit_and_crossing_zero_too():
    smoother = Smoother(LIMITS, period_s=0.1)
    smoother.sent_now(Twist(0.5, 0.0), 0.0)
    slower = smoother.smooth(Twist(0.0, 0.0), 0.1)
    assert slower.linear_x == pytest.approx(0.3)  # 2 m/s^2 for 0.1 s
    smoother.sent_now(Twist(0.1, 0.0), 0.0)
    reverse = smoother.smooth(Twist(-0.3, 0.0), 0.1)
    assert reverse.linear_x == pytest.approx(-0.1)  # the opposite side: Nav2 decelerates across zero


def test_a_base_standing_for_long_still_ramps_from_one_cycle():
    smoother = Smoother(LIMITS, period_s=0.05)
    smoother.sent_now(Twist(0.0, 0.0), 0.0)
    assert smoother.smooth(Twist(0.5, 0.0), 30.0).linear_x == pytest.approx(0.05)
