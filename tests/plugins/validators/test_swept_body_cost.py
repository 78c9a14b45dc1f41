"""``swept_body``'s work is bounded by what can matter, not by the speed asked (issue 52, item 8).

The work is counted, never timed: the points the rule hands to the geometry (``near_path`` and
``contact_times``, both by their names in the rule's module), through monkeypatched counters.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

import safeembodai_plugins.validators.swept_body as swept_body
from safeembodai_core import Guard, RobotSpec
from safeembodai_core.ros import CommandFilter, LaserScan, Twist

LONG = [(400.0, 150.0), (-400.0, 150.0), (-400.0, -150.0), (400.0, -150.0)]


@pytest.fixture
def work(monkeypatch):
    """A list that receives the number of points of every geometric evaluation the rule asks for."""
    counted: list[int] = []
    for name in ("near_path", "contact_times"):
        real = getattr(swept_body, name)

        def counting(points, *args, _real=real, **kwargs):
            counted.append(len(points))
            return _real(points, *args, **kwargs)

        monkeypatch.setattr(swept_body, name, counting)
    return counted


def scan_of(ranges, field_of_view=2 * math.pi, range_max=20.0):
    return LaserScan(angle_min=-field_of_view / 2, angle_increment=field_of_view / len(ranges), ranges=ranges,
                     range_min=0.1, range_max=range_max)


def decide(scan, twist):
    node = CommandFilter(Guard())
    node.on_scan(scan, 0.0)
    return node.on_command(twist, 0.01)


def test_an_absurd_speed_into_a_scan_of_no_readings_costs_what_a_sane_one_does(work):
    """The issue's scan (7,200 beams, none read; 20 m of range here): at 1 m/s the first touch of unseen
    space is found within the first look along the path, and so it is at 100 m/s and 10 km/s."""
    scan = scan_of([math.nan] * 7200)
    evaluated = {}
    for speed in (1.0, 100.0, 1e4):
        work.clear()
        decision = decide(scan, Twist(speed, 0.0))
        assert decision.action != "forward" and decision.collision_time_s is not None
        evaluated[speed] = sum(work)
    assert evaluated[100.0] == evaluated[1e4] <= 2 * evaluated[1.0]


def test_unseen_space_far_from_the_path_is_not_sampled(work):
    """A 270 degree scanner in the open, its 90 degrees behind unseen: 100 m/s ahead looks along the
    whole 20 m of range ahead, but only at the stretches of ray near the path, a fifth or less of the
    samples the unseen wedge holds."""
    scan = scan_of([math.inf] * 5400, field_of_view=1.5 * math.pi)
    decision = decide(scan, Twist(100.0, 0.0))
    assert decision.action == "limit" and decision.collision_time_s == pytest.approx((20_000 - 170) / 100_000)
    step = 20.0  # SweptBodyOptions.unseen_step_mm's default
    wedge = (math.pi / 4) * 20_000.0 ** 2 / step ** 2  # the wedge's samples, about step_mm apart
    assert sum(work) < wedge / 5


def cases():
    rng = np.random.default_rng(52)
    for k in range(8):
        ranges = rng.uniform(0.3, 12.0, 1440)
        ranges[rng.random(1440) < 0.3] = math.nan
        if k % 2:
            ranges[::2] = math.inf  # shadows everywhere
        twist = Twist(float(rng.uniform(-4.0, 30.0)), float(rng.choice([0.0, rng.uniform(-2.0, 2.0)])))
        since = None if k % 3 else (float(rng.uniform(-300, 300)), float(rng.uniform(-300, 300)), 20.0)
        yield scan_of(ranges, range_max=10.0), twist, since, k % 4 == 1


@pytest.mark.parametrize("scan, twist, since, polygon", list(cases()))
def test_the_bounded_work_judges_exactly_as_looking_everywhere_does(monkeypatch, scan, twist, since, polygon):
    """Looking in stages and only near the path changes nothing in the report: the same times, the
    same reasons, as sampling every ray out to the whole motion's reach."""
    guard = Guard(robot=RobotSpec(radius_mm=428, footprint_mm=LONG) if polygon else RobotSpec())

    def report():
        r = guard.check_twist(twist, 1.5, lidar_mm=scan, since_scan=since)
        return r.valid, r.collision_time_s, r.contact, r.obstacle_time_s, r.unseen_time_s, r.reasons

    bounded = report()
    monkeypatch.setattr(swept_body, "FIRST_LOOK_MM", math.inf)
    monkeypatch.setattr(swept_body, "_CULL_ABOVE", math.inf)
    assert bounded == report()
