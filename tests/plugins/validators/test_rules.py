"""``command_limits`` and ``lidar_clearance`` (the paper's V(C))."""

from __future__ import annotations

import re

import numpy as np
import pytest

from safeembodai_core.models import ControlLimits, LidarScan, Straight, Turn
from safeembodai_core.validation.context import ValidationContext, validate_plan


def fwd(d: float) -> Straight:
    return Straight(command="straight", direction="forward", distance=d)


def back(d: float) -> Straight:
    return Straight(command="straight", direction="backward", distance=d)


def left(a: float) -> Turn:
    return Turn(command="turn", direction="left", angle=a)


def scan(beams: dict[tuple[int, int], float] | None = None, n: int = 360, default: float = np.inf,
         max_range: float = 6000.0) -> LidarScan:
    """A scan with ``default`` everywhere and the given value on beam ranges [a, b] (degrees, n=360)."""
    ranges = np.full(n, default, dtype=float)
    for (a, b), value in (beams or {}).items():
        for angle in range(a, b + 1):
            ranges[angle % n] = value
    return LidarScan(ranges_mm=ranges, max_range_mm=max_range)


def context(lidar: LidarScan | None, **kwargs) -> ValidationContext:
    return ValidationContext(scan=lidar, **kwargs)


@pytest.fixture
def rule(plugins):
    def build(name: str, **options):
        return plugins.registry.build("validator", name, options)
    return build


# -- command_limits ---------------------------------------------------------------------------


def test_command_limits_follow_the_scenario_limits_by_default(rule):
    limits = rule("command_limits")
    tight = context(None, limits=ControlLimits(max_distance_mm=300, max_angle_deg=45))
    assert limits.validate(fwd(299), tight).valid and not limits.validate(fwd(350), tight).valid
    assert limits.validate(left(44), tight).valid and not limits.validate(left(60), tight).valid
    assert limits.validate(fwd(350), context(None)).valid  # default limits: < 400 mm


def test_command_limits_options_tighten_and_explain_units(rule):
    limits = rule("command_limits", max_distance_mm=200, min_distance_mm=10, min_angle_deg=5)
    verdict = limits.validate(fwd(250), context(None))
    assert (not verdict.valid and "10 < distance < 200 (mm)" in verdict.reason
            and "straight forward 250 mm" in verdict.reason)
    assert not limits.validate(fwd(5), context(None)).valid
    assert not limits.validate(left(2), context(None)).valid and limits.validate(left(10), context(None)).valid


def test_command_limits_refuse_non_finite_values_smuggled_past_parsing(rule):
    sneaky = Straight.model_construct(command="straight", direction="forward", distance=float("nan"), justification="")
    assert not rule("command_limits").validate(sneaky, context(None)).valid


# -- lidar_clearance: V(C) = AND over θ in [-r, r] of l(θ) - |d| >= dist ---------------------


def test_clearance_is_the_papers_inequality_at_its_boundary(rule):
    clearance = rule("lidar_clearance", half_angle_deg=30, safety_distance_mm=250)
    wall = scan({(-30, 30): 600.0})
    assert clearance.validate(fwd(350), context(wall)).valid  # 600 - 350 = 250 >= 250
    refused = clearance.validate(fwd(351), context(wall))
    assert not refused.valid
    assert "obstacle 600 mm ahead" in refused.reason and "going forward, at most 350 mm is safe" in refused.reason


def test_clearance_checks_only_the_sector_and_turns_always_pass(rule):
    clearance = rule("lidar_clearance", half_angle_deg=30, safety_distance_mm=250)
    beside = scan({(31, 60): 200.0, (-60, -31): 200.0})
    assert clearance.validate(fwd(390), context(beside)).valid
    assert not rule("lidar_clearance", half_angle_deg=35).validate(fwd(390), context(beside)).valid
    assert clearance.validate(left(45), context(scan(default=10.0))).valid


def test_backward_motion_checks_the_beams_behind(rule):
    clearance = rule("lidar_clearance")
    behind = scan({(160, 200): 400.0})
    assert clearance.validate(fwd(390), context(behind)).valid
    refused = clearance.validate(back(200), context(behind))
    assert (not refused.valid and "400 mm behind" in refused.reason
            and "going backward, at most 150 mm is safe" in refused.reason)
    assert clearance.validate(back(150), context(behind)).valid


def test_no_return_is_free_up_to_range_and_no_reading_refuses(rule):
    clearance = rule("lidar_clearance", safety_distance_mm=250)
    assert clearance.validate(fwd(390), context(scan())).valid  # all inf
    short_range = scan(max_range=500.0)
    assert not clearance.validate(fwd(300), context(short_range)).valid  # only 500 mm are known to be free
    missing = scan({(10, 10): np.nan})
    refused = clearance.validate(fwd(50), context(missing))
    assert not refused.valid and "no LiDAR reading at 10 deg" in refused.reason
    assert clearance.validate(fwd(50), context(scan({(90, 90): np.nan}))).valid  # outside the sector


def test_clearance_judges_each_signal_from_the_planned_pose(rule):
    clearance = rule("lidar_clearance")
    wall_left = scan({(60, 120): 450.0})
    verdicts = validate_plan([fwd(300), left(80), fwd(300)], context(wall_left), [("lidar_clearance", clearance)])
    assert [v.valid for v in verdicts] == [True, True, False]
    assert verdicts[2].signal_index == 2


def test_refusal_advice_is_accepted_when_followed(rule):
    clearance = rule("lidar_clearance")
    rng = np.random.default_rng(3)
    for _ in range(40):
        lidar = LidarScan(ranges_mm=rng.uniform(300, 1200, size=360), max_range_mm=6000.0)
        verdict = clearance.validate(fwd(390), context(lidar))
        match = re.search(r"going forward, at most (\d+) mm is safe", verdict.reason)
        if match and int(match.group(1)) >= 1:
            assert clearance.validate(fwd(int(match.group(1))), context(lidar)).valid


@pytest.mark.parametrize("name", ["lidar_clearance", "footprint_sweep"])
def test_malformed_scans_are_refused_with_the_rule_named(rule, name):
    lidar = scan()
    lidar.ranges_mm = np.zeros((180, 2))  # e.g. an attacker or a driver replacing the array
    verdict = validate_plan([fwd(100)], context(lidar), [(name, rule(name))])[0]
    assert not verdict.valid and verdict.rule == name and f"{name}: LiDAR scan has shape (180, 2)" in verdict.reason
    counted = rule(name, expected_beams=720)
    verdict = validate_plan([fwd(100)], context(scan()), [(name, counted)])[0]
    assert not verdict.valid and "360 beams; this rule expects 720" in verdict.reason
    verdict = validate_plan([fwd(100)], context(None), [(name, rule(name))])[0]
    assert not verdict.valid and "needs a LiDAR scan" in verdict.reason


def test_rule_options_are_checked(plugins):
    from safeembodai_core.plugin.registry import ComponentOptionsError

    with pytest.raises(ComponentOptionsError, match="half_angle_deg"):
        plugins.registry.build("validator", "lidar_clearance", {"half_angle_deg": 120})
    with pytest.raises(ComponentOptionsError, match="margin"):
        plugins.registry.build("validator", "footprint_sweep", {"margin": 10})
