"""``lidar_clearance``'s dist is honoured as given, with an explicit measuring point.

It used to be raised silently to the robot's radius (``max(dist, radius)``), so the authors'
release setting -- unsafe when ``scan - |d| < 100 mm``, over ±10 deg -- could not be expressed.
"""

from __future__ import annotations

import numpy as np
import pytest

from safeembodai_core.contracts.components import RobotSpec
from safeembodai_core.plugin.registry import ComponentOptionsError
from safeembodai_core.validation.context import ValidationContext, validate_plan

from .test_rules import fwd, left, scan

RELEASE = {"half_angle_deg": 10, "safety_distance_mm": 100, "measured_from": "lidar", "allow_below_radius": True}


@pytest.fixture
def clearance(plugins):
    def build(**options):
        return plugins.registry.build("validator", "lidar_clearance", options)
    return build


def wall(at_mm: float, half_width: int = 30) -> ValidationContext:
    return ValidationContext(scan=scan({(-half_width, half_width): at_mm}, default=5000.0), robot=RobotSpec())


def test_unset_dist_keeps_250_mm_from_the_lidar_or_the_radius_if_larger(clearance):
    assert clearance().validate(fwd(350), wall(600)).valid and not clearance().validate(fwd(351), wall(600)).valid
    big = ValidationContext(scan=wall(600).scan, robot=RobotSpec(radius_mm=320, width_mm=640, length_mm=640))
    assert clearance().validate(fwd(280), big).valid and not clearance().validate(fwd(281), big).valid


def test_a_dist_inside_the_body_is_refused_naming_the_option_and_the_radius(clearance):
    rule = clearance(safety_distance_mm=100)
    refused = rule.validate(fwd(50), wall(2000))  # clear by any measure: the setting, not the motion, is refused
    assert not refused.valid
    for words in ("safety_distance_mm 100", "measured_from: lidar", "robot's radius (170 mm)", "allow_below_radius"):
        assert words in refused.reason
    assert rule.validate(left(30), wall(2000)).valid  # turns stay valid under V(C)
    assert clearance(safety_distance_mm=170).validate(fwd(399), wall(569)).valid  # exactly the radius is allowed


def test_the_authors_release_setting_is_expressible_and_exact(clearance):
    rule = clearance(**RELEASE)
    assert rule.validate(fwd(399), wall(499, half_width=10)).valid  # 499 - 399 = 100: not < 100
    refused = rule.validate(fwd(399), wall(498, half_width=10))
    assert (not refused.valid
            and "less than the 100 mm required; going forward, at most 398 mm is safe" in refused.reason)
    beside = ValidationContext(scan=scan({(11, 30): 300.0}, default=5000.0))
    assert rule.validate(fwd(399), beside).valid  # ±10 deg only


def test_dist_measured_from_the_body_adds_the_radius(clearance):
    rule = clearance(safety_distance_mm=80, measured_from="body")
    assert rule.validate(fwd(350), wall(600)).valid  # 600 - 350 = 250 = 170 + 80
    refused = rule.validate(fwd(351), wall(600))
    assert not refused.valid
    assert "less than the 250 mm required (80 mm from the body + the robot's 170 mm radius)" in refused.reason
    big = ValidationContext(scan=wall(600).scan, robot=RobotSpec(radius_mm=300, width_mm=600, length_mm=600))
    assert rule.validate(fwd(220), big).valid and not rule.validate(fwd(221), big).valid


@pytest.mark.parametrize(("options", "words"), [
    ({"measured_from": "body"}, "give safety_distance_mm too"),
    ({"allow_below_radius": True}, "give safety_distance_mm too"),
    ({"safety_distance_mm": 50, "measured_from": "body", "allow_below_radius": True}, "measured_from: lidar only"),
    ({"measured_from": "centre", "safety_distance_mm": 50}, "measured_from"),
])
def test_options_that_say_nothing_or_contradict_are_refused_when_built(clearance, options, words):
    with pytest.raises(ComponentOptionsError, match="lidar_clearance") as error:
        clearance(**options)
    assert words in str(error.value)


def test_in_a_plan_the_setting_refusal_reaches_every_straight(clearance):
    verdicts = validate_plan([fwd(100), left(30), fwd(100)], wall(3000), [("c", clearance(safety_distance_mm=100))])
    assert [v.valid for v in verdicts] == [False, True, False]
    assert np.all(["robot's radius" in v.reason for v in verdicts if not v.valid])
