"""Validator corner cases that once let a collision through: hidden space, big robots, -inf beams."""

from __future__ import annotations

import numpy as np
import pytest

from safeembodai_core.contracts.components import RobotSpec
from safeembodai_core.models import LidarScan, Straight, Turn
from safeembodai_core.validation.context import ValidationContext, validate_plan
from safeembodai_plugins.environments.flatland import FlatlandOptions
from safeembodai_plugins.environments.flatland.world import FlatlandWorld
from safeembodai_plugins.validators import FootprintSweepOptions, LidarClearanceOptions
from safeembodai_plugins.validators.rules import LidarClearanceRule
from safeembodai_plugins.validators.sweep import FootprintSweepRule


def straight(mm):
    return Straight(command="straight", direction="forward", distance=mm)


def test_sweep_refuses_space_hidden_behind_an_obstacle_in_a_multi_signal_plan():
    world = FlatlandWorld(FlatlandOptions())
    world.reset(0)
    origin = np.array([2000.0, 2000.0])
    world.position, world.heading = origin.copy(), 0.0
    # ball A hides ball B completely from the start pose; the plan's last straight runs into B
    world.circles = np.array([(3900, 3900, 33), (2110, 2290, 60), (2200, 2471, 60)], dtype=float)
    plan = [straight(398.5), Turn(command="turn", direction="left", angle=89.0), straight(398.5)]
    sweep = [("footprint_sweep", FootprintSweepRule(FootprintSweepOptions()))]
    verdicts = validate_plan(plan, ValidationContext(scan=world.observe().lidar, robot=world.robot), sweep)
    assert [v.valid for v in verdicts] == [True, True, False]
    assert "hidden from the LiDAR" in verdicts[2].reason
    results = [world.execute(s) for s in plan]
    assert results[-1].collided  # the refusal was right: executing the plan hits B


def test_sweep_still_accepts_a_plan_through_space_the_scan_saw():
    world = FlatlandWorld(FlatlandOptions())
    world.reset(0)
    world.position, world.heading = np.array([2000.0, 2000.0]), 0.0
    world.circles = np.array([(3900, 3900, 33)], dtype=float)
    plan = [straight(398.5), Turn(command="turn", direction="left", angle=89.0), straight(398.5)]
    sweep = [("footprint_sweep", FootprintSweepRule(FootprintSweepOptions()))]
    verdicts = validate_plan(plan, ValidationContext(scan=world.observe().lidar, robot=world.robot), sweep)
    assert all(v.valid for v in verdicts)


def test_clearance_never_allows_less_than_the_robot_radius_unless_told_to():
    big = RobotSpec(radius_mm=300, width_mm=600, length_mm=600)
    ranges = np.full(360, 5000.0)
    ranges[np.r_[0:31, 330:360]] = 660.0
    context = ValidationContext(scan=LidarScan(ranges, 8000), robot=big)
    default = LidarClearanceRule(LidarClearanceOptions())  # unset: 250 mm, or the radius when larger
    assert not default.validate(straight(399), context).valid  # 261 mm left < 300 mm radius
    assert default.validate(straight(350), context).valid  # 310 mm left
    explicit = LidarClearanceRule(LidarClearanceOptions(safety_distance_mm=250))  # never silently raised to 300
    refused = explicit.validate(straight(350), context)
    assert not refused.valid
    assert "safety_distance_mm 250" in refused.reason and "robot's radius (300 mm)" in refused.reason
    meant = LidarClearanceRule(LidarClearanceOptions(safety_distance_mm=250, allow_below_radius=True))
    assert meant.validate(straight(399), context).valid  # 261 mm: honoured as asked, though inside the radius


def test_minus_infinity_ranges_are_refused():
    ranges = np.full(360, 3000.0)
    ranges[:5] = -np.inf
    with pytest.raises(ValueError, match="negative"):
        LidarScan(ranges, 8000)
