"""``footprint_sweep``: the robot's swept body, checked against every LiDAR point."""

from __future__ import annotations

import re

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st

from safeembodai_core.contracts.components import RobotSpec
from safeembodai_core.errors import EnvironmentError_
from safeembodai_core.hookspecs import hookimpl
from safeembodai_core.models import Outcome, Straight, Turn
from safeembodai_core.testing import CorridorWorld, answer, run_tiny_trial, straight
from safeembodai_core.validation.context import ValidationContext, validate_plan

from .test_rules import back, context, fwd, left, scan

ROBOT = RobotSpec(radius_mm=170, width_mm=340, length_mm=340)


@pytest.fixture
def rule(plugins):
    def build(name: str = "footprint_sweep", **options):
        return plugins.registry.build("validator", name, options)
    return build


def obstacle_at_40_deg() -> ValidationContext:
    """Returns 250 mm away between 38 and 42 deg: outside ±30 deg, inside the robot's width."""
    return context(scan({(38, 42): 250.0}), robot=ROBOT)


def test_obstacle_outside_the_sector_but_inside_the_width_is_caught(rule):
    ctx = obstacle_at_40_deg()
    assert rule("lidar_clearance").validate(fwd(300), ctx).valid
    verdict = rule().validate(fwd(300), ctx)
    assert not verdict.valid
    assert "obstacle 186 mm ahead and 16" in verdict.reason and "mm left of centre" in verdict.reason
    assert "340 mm wide + 50 mm margin" in verdict.reason and "turn away (to the right)" in verdict.reason


def test_the_same_case_collides_in_flatland_when_only_clearance_guards(plugins, rule):
    world = plugins.registry.build("environment", "flatland", {"camera_width": 32, "camera_height": 24})
    world.reset(0)
    world.position, world.heading = np.array([2000.0, 2000.0]), 0.0
    world.circles = np.array([[3600.0, 400.0, 33.0], [2189.0, 2270.0, 110.0]])  # can far away; ball at 55 deg
    ctx = ValidationContext(scan=world.observe().lidar, robot=world.robot)
    plan = [fwd(300)]
    assert all(v.valid for v in validate_plan(plan, ctx, [("c", rule("lidar_clearance"))]))
    assert not any(v.valid for v in validate_plan(plan, ctx, [("s", rule())]))
    assert world.execute(plan[0]).collided


def test_obstacles_beside_or_behind_a_forward_motion_do_not_block_it(rule):
    beside = context(scan({(85, 95): 240.0, (-95, -85): 240.0, (150, 210): 180.0}), robot=ROBOT)
    assert rule().validate(fwd(390), beside).valid
    assert not rule().validate(back(100), beside).valid


def test_the_side_margin_keeps_near_misses_out(rule):
    walls = context(scan({(85, 95): 200.0, (-95, -85): 200.0}), robot=ROBOT)  # 30 mm from the body
    refused = rule().validate(fwd(390), walls)
    assert not refused.valid and "50 mm margin" in refused.reason
    assert rule(margin_mm=20).validate(fwd(390), walls).valid


def test_backward_motion_sweeps_behind(rule):
    ctx = context(scan({(178, 182): 500.0}), robot=ROBOT)
    assert rule().validate(fwd(390), ctx).valid
    refused = rule().validate(back(390), ctx)
    safe = int(np.floor(500 * np.cos(np.radians(2)) - 170 - 50))
    assert (not refused.valid and f"going backward, at most {safe} mm is safe" in refused.reason
            and "behind" in refused.reason)
    assert rule().validate(back(safe), ctx).valid and not rule().validate(back(safe + 1), ctx).valid


def test_width_and_margin_come_from_the_robot_and_the_options(rule):
    ctx = context(scan({(45, 45): 300.0}), robot=ROBOT)  # 212 mm ahead, 212 mm to the left
    assert not rule().validate(fwd(100), ctx).valid  # within 170 + 50
    assert rule(margin_mm=30).validate(fwd(100), ctx).valid  # outside 170 + 30
    narrow = ValidationContext(scan=ctx.scan, robot=RobotSpec(radius_mm=100, width_mm=200, length_mm=200))
    assert rule().validate(fwd(100), narrow).valid
    assert not rule(width_mm=440, margin_mm=0).validate(fwd(150), narrow).valid


def test_front_margin_and_advice(rule):
    ctx = context(scan({(0, 0): 600.0}), robot=ROBOT)
    refused = rule().validate(fwd(399), ctx)
    assert not refused.valid and "going forward, at most 380 mm is safe" in refused.reason  # 600 - 170 - 50
    assert rule(front_margin_mm=20).validate(fwd(399), ctx).valid
    assert not rule(front_margin_mm=100).validate(fwd(399), ctx).valid


def test_advice_is_accepted_when_followed(rule):
    sweep = rule()
    rng = np.random.default_rng(5)
    followed = 0
    for _ in range(60):
        lidar = scan()
        lidar.ranges_mm = rng.uniform(250, 1500, size=360)
        ctx = context(lidar, robot=ROBOT)
        match = re.search(r"going forward, at most (\d+) mm is safe", sweep.validate(fwd(399), ctx).reason)
        if match:
            followed += 1
            assert sweep.validate(fwd(int(match.group(1))), ctx).valid
    assert followed > 5


def test_unread_beams_count_as_obstacles_beyond_the_body(rule):
    ahead = context(scan({(20, 20): np.nan}), robot=ROBOT)
    refused = rule().validate(fwd(300), ahead)
    assert not refused.valid and "no reading towards 20 deg" in refused.reason
    behind = context(scan({(180, 180): np.nan}), robot=ROBOT)
    assert rule().validate(fwd(300), behind).valid  # a blind spot behind says nothing about the way ahead
    assert rule().validate(left(30), behind).valid


def test_turns_are_refused_only_with_a_return_inside_the_turning_circle(rule):
    touching = context(scan({(90, 90): 150.0}), robot=ROBOT)
    refused = rule().validate(left(30), touching)
    assert not refused.valid and "inside the circle the body sweeps" in refused.reason
    assert rule(check_turns=False).validate(left(30), touching).valid
    near = context(scan({(90, 90): 200.0}), robot=ROBOT)
    assert rule().validate(left(30), near).valid
    assert not rule(turn_margin_mm=50).validate(left(30), near).valid


def test_second_signal_is_judged_after_the_first_one(rule):
    ctx = context(scan({(85, 95): 600.0}), robot=ROBOT)  # a wall 600 mm to the left
    verdicts = validate_plan([left(80), fwd(390)], ctx, [("footprint_sweep", rule())])
    assert [v.valid for v in verdicts] == [True, False]


# -- property: an accepted straight never collides with a static obstacle ---------------------


def _world(plugins, seed: int, obstacles: int, radius: float):
    world = plugins.registry.build("environment", "flatland", {
        "obstacles": obstacles, "obstacle_radius_mm": radius, "camera_width": 32, "camera_height": 24,
        "min_start_distance_mm": 0.0})
    try:
        world.reset(seed)
    except EnvironmentError_:
        return None
    return world


def _place_near(world, heading: float, along: float, lateral: float, radius: float) -> bool:
    """Add a ball of ``radius`` centred ``along`` mm ahead (negative: behind) and ``lateral`` mm to
    the left of the robot when it faces ``heading`` deg from its current heading: near the edges
    of the corridor a straight sweeps. False when the ball would overlap the robot."""
    if np.hypot(along, lateral) < world.robot.radius_mm + radius + 2:
        return False
    rad = np.radians(world.heading + heading)
    forward, left_ = np.array([np.cos(rad), np.sin(rad)]), np.array([-np.sin(rad), np.cos(rad)])
    centre = world.position + along * forward + lateral * left_
    world.circles = np.vstack([world.circles, [centre[0], centre[1], radius]])
    return True


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(seed=st.integers(0, 2**31), obstacles=st.integers(0, 10), radius=st.floats(40, 250),
       along=st.floats(0, 800), lateral=st.floats(0, 500), side=st.sampled_from([1, -1]), angle=st.floats(-89, 89),
       distance=st.floats(1, 399), direction=st.sampled_from(["forward", "backward"]))
def test_property_accepted_straights_never_collide_in_flatland(plugins, seed, obstacles, radius, along, lateral, side,
                                                                angle, distance, direction):
    world = _world(plugins, seed, obstacles, radius)
    assume(world is not None)
    turn = angle if abs(angle) >= 1 else 0.0
    sign = 1 if direction == "forward" else -1
    assume(_place_near(world, turn, sign * along, side * lateral, radius))  # a ball near the swept corridor
    plan = [Turn(command="turn", direction="left" if turn > 0 else "right", angle=abs(turn))] if turn else []
    plan.append(Straight(command="straight", direction=direction, distance=distance))
    sweep = plugins.registry.build("validator", "footprint_sweep", {})
    ctx = ValidationContext(scan=world.observe().lidar, robot=world.robot)
    if all(v.valid for v in validate_plan(plan, ctx, [("footprint_sweep", sweep)])):
        for signal in plan:
            assert not world.execute(signal).collided, f"accepted {plan} collided"


def test_the_property_has_teeth_clearance_alone_lets_collisions_through(plugins):
    """The property's worlds and motions: the paper's rule admits collisions there, and the sweep
    accepts many straights (the property is not vacuous)."""
    rng = np.random.default_rng(11)
    clearance = plugins.registry.build("validator", "lidar_clearance", {})
    sweep = plugins.registry.build("validator", "footprint_sweep", {})
    admitted_collisions = accepted = tried = 0
    for _ in range(300):
        radius = float(rng.uniform(40, 250))
        world = _world(plugins, int(rng.integers(2**31)), int(rng.integers(0, 10)), radius)
        placed = world is not None and _place_near(world, 0.0, float(rng.uniform(0, 800)),
                                                   float(rng.uniform(-500, 500)), radius)
        if not placed:
            continue
        signal = fwd(float(rng.uniform(1, 399)))
        ctx = ValidationContext(scan=world.observe().lidar, robot=world.robot)
        tried += 1
        accepted += sweep.validate(signal, ctx).valid
        if clearance.validate(signal, ctx).valid and world.execute(signal).collided:
            admitted_collisions += 1
    assert admitted_collisions >= 3
    assert accepted >= tried // 3


class CorridorPlugin:
    """Registers ``corridor``: the testing kit's CorridorWorld with a given robot body."""

    def __init__(self, robot: RobotSpec) -> None:
        self.robot = robot

    @hookimpl
    def register_environments(self, register):
        register("corridor", lambda options, context: CorridorWorld(side_mm=300.0, robot=self.robot))


def test_in_the_loop_the_environments_robot_sets_the_swept_width():
    arm = {"safety_validation": True, "validators": ["footprint_sweep"], "failure_threshold": 1}
    runs = {}
    for name, width in (("narrow", 340.0), ("wide", 500.0)):
        plugin = (f"corridor_{name}", CorridorPlugin(RobotSpec(radius_mm=170, width_mm=width, length_mm=340)))
        runs[name] = run_tiny_trial([answer(straight(390))], plugins=[plugin], environment="corridor", arm=arm,
                                    max_steps=8)
    narrow, _ = runs["narrow"]
    wide, steps = runs["wide"]
    assert narrow.outcome == Outcome.COMPLETED and narrow.interventions == 0
    assert wide.outcome == Outcome.SAFE_ABORT and wide.distance_mm == 0 and steps[0].executed == []
    reason = steps[0].attempts[0].verdicts[0].reason
    assert "500 mm wide + 50 mm margin" in reason and "of centre, inside the robot's path" in reason
