"""``geometry_msgs/Twist`` held for a while, judged as the arc it sweeps (issue 23, part 2); read
decoded or as rosbridge sends it (JSON), strictly."""

from __future__ import annotations

import json
import math
from types import SimpleNamespace

import numpy as np
import pytest

from safeembodai_core import Guard
from safeembodai_core.models import Straight, Turn
from safeembodai_core.ros import Twist, arc_signals


def end_of(signals) -> tuple[float, float, float]:
    """Where the signals leave the robot from the origin facing +x: x, y (mm), heading (degrees)."""
    x = y = heading = 0.0
    for s in signals:
        if isinstance(s, Turn):
            heading += s.signed_angle_deg
        else:
            x += s.signed_distance_mm * math.cos(math.radians(heading))
            y += s.signed_distance_mm * math.sin(math.radians(heading))
    return x, y, heading


@pytest.mark.parametrize("v, w, t", [(0.2, 0.5, 3.0), (-0.15, -0.3, 2.0), (0.3, 0.0, 1.5), (0.0, 1.0, 1.0)])
def test_the_pieces_follow_the_arc(v, w, t):
    signals = arc_signals(Twist(v, w), t)
    x, y, heading = end_of(signals)
    if w == 0:
        ex, ey = v * 1000 * t, 0.0
    else:
        radius = v * 1000 / w
        ex, ey = radius * math.sin(w * t), radius * (1 - math.cos(w * t))
    assert math.hypot(x - ex, y - ey) < 2.0  # mm: the chords of 5-degree pieces lie on the arc
    assert heading == pytest.approx(math.degrees(w * t), abs=1e-6)
    assert all((s.distance <= 50.0 if isinstance(s, Straight) else s.angle <= 5.0) for s in signals)


def wall_ahead(distance_mm: float) -> np.ndarray:
    ranges = np.full(360, 5000.0)
    ranges[np.r_[0:40, 320:360]] = distance_mm
    return ranges


def test_a_command_into_a_wall_is_refused_with_the_longest_safe_duration():
    """0.2 m/s for 3 s towards a wall 600 mm ahead: lidar_clearance keeps 250 mm, so about 350 mm
    (1.75 s) of it is safe; the safe duration passes and a tenth of a second more does not."""
    guard = Guard(rules=["command_limits", "lidar_clearance"])
    report = guard.check_twist(Twist(0.2, 0.0), 3.0, lidar_mm=wall_ahead(600.0))
    assert not report.valid
    assert 1.6 <= report.safe_duration_s <= 1.76
    assert report.reasons[0].startswith("twist linear.x 0.2 m/s, angular.z 0 rad/s for 3 s: refused; at most 1.7")
    assert guard.check_twist(Twist(0.2, 0.0), report.safe_duration_s, lidar_mm=wall_ahead(600.0)).valid
    assert not guard.check_twist(Twist(0.2, 0.0), report.safe_duration_s + 0.1, lidar_mm=wall_ahead(600.0)).valid
    # turning on the spot sweeps nothing: accepted, whatever is ahead
    assert guard.check_twist((0.0, 0.8), 2.0, lidar_mm=wall_ahead(300.0)).valid


def test_the_arc_is_judged_not_its_endpoints():
    """An obstacle 700 mm away at 50 degrees left: an arc curving left (radius 400 mm) sweeps into
    it and is refused; the mirror arc curving right passes; a straight of the same length, which
    never turns towards it, passes too."""
    ranges = np.full(360, 5000.0)
    ranges[40:61] = 700.0
    guard = Guard(rules=["command_limits", "lidar_clearance"])
    left = guard.check_twist(Twist(0.2, 0.5), 3.0, lidar_mm=ranges)
    right = guard.check_twist(Twist(0.2, -0.5), 3.0, lidar_mm=ranges)
    assert not left.valid and right.valid
    assert left.safe_duration_s < 3.0
    assert guard.check_twist(Twist(0.2, 0.0), 3.0, lidar_mm=ranges).valid


def test_from_ros_reads_a_decoded_message_and_refuses_what_it_cannot_judge():
    def vector(x=0.0, y=0.0, z=0.0):
        return SimpleNamespace(x=x, y=y, z=z)

    twist = Twist.from_ros(SimpleNamespace(linear=vector(0.25), angular=vector(z=-0.4)))
    assert (twist.linear_x, twist.angular_z) == (0.25, -0.4)
    stamped = SimpleNamespace(header=None, twist=SimpleNamespace(linear=vector(0.1), angular=vector()))
    assert Twist.from_ros(stamped).linear_x == 0.1
    with pytest.raises(ValueError, match="linear.y = 0.3: only a planar command"):
        Twist.from_ros(SimpleNamespace(linear=vector(0.1, 0.3), angular=vector()))
    with pytest.raises(ValueError, match="Twist.linear.x must be finite"):
        Twist.from_ros(SimpleNamespace(linear=vector(math.nan), angular=vector()))
    with pytest.raises(ValueError, match="not a geometry_msgs/Twist"):
        Twist.from_ros(SimpleNamespace(linear=0.2))
    with pytest.raises(ValueError, match="duration_s must be a finite number"):
        arc_signals(Twist(0.1, 0.0), math.nan)
    with pytest.raises(ValueError, match="angular_z must be finite"):
        Guard(rules=["lidar_clearance"]).check_twist((0.1, math.inf), 1.0, lidar_mm=wall_ahead(600.0))


def test_from_ros_reads_twist_and_twist_stamped_as_rosbridge_sends_them():
    frame = json.loads('{"op": "publish", "topic": "/cmd_vel", "msg": {"linear": {"x": 0.25, "y": 0, "z": 0}, '
                       '"angular": {"x": 0, "y": 0, "z": -0.4}}}')
    twist = Twist.from_ros(frame["msg"])
    assert (twist.linear_x, twist.angular_z, twist.linear_y) == (0.25, -0.4, 0.0)
    stamped = json.loads('{"header": {"stamp": {"sec": 1718000000, "nanosec": 0}, "frame_id": "base_link"}, '
                         '"twist": {"linear": {"x": -0.1, "y": 0.2, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, '
                         '"z": 1}}}')
    assert Twist.from_ros(stamped, holonomic=True) == Twist(-0.1, 1.0, 0.2)
    with pytest.raises(ValueError, match="linear.y = 0.2: only a planar command"):
        Twist.from_ros(stamped)


LINEAR = '"linear": {"x": 0.2, "y": 0.0, "z": 0.0}'


@pytest.mark.parametrize("text, message", [
    ('{"linear": {"x": 0.2, "y": 0.0}, "angular": {"x": 0, "y": 0, "z": 0}}',
     r"not a geometry_msgs/Vector3 \(Twist.linear\): no z"),
    (f'{{{LINEAR}}}', "not a geometry_msgs/Twist: no angular"),
    (f'{{{LINEAR}, "angular": {{"x": 0, "y": 0, "z": true}}}}', "Twist.angular.z must be a number, got True"),
    (f'{{{LINEAR}, "angular": {{"x": 0, "y": 0, "z": "0.5"}}}}', "Twist.angular.z must be a number, got '0.5'"),
    (f'{{{LINEAR}, "angular": {{"x": 0, "y": 0, "z": null}}}}', "Twist.angular.z must be a number, got None"),
    (f'{{{LINEAR}, "angular": {{"x": 0, "y": 0, "z": 1{"0" * 400}}}}}',
     "Twist.angular.z must be a number, got an integer of 1329 bits"),
    (f'{{{LINEAR}, "angular": {{"x": 0, "y": 0, "z": [0.5]}}}}', "Twist.angular.z must be a number"),
    (f'{{{LINEAR}, "angular": 0.5}}', "Twist.angular must be an object of x, y, z, got 0.5"),
    (f'{{{LINEAR}, "angular": {{"x": 0, "y": 0, "z": 0, "w": 1}}}}', "unknown field 'w'"),
    (f'{{{LINEAR}, "angular": {{"x": 0, "y": 0, "z": 0}}, "speed": 9}}', "not a geometry_msgs/Twist: unknown field"),
    ('{"twist": {"linear": {"x": 0.2, "y": 0, "z": 0}, "angular": {"x": 0, "y": 0, "z": 0}}}',
     "not a geometry_msgs/TwistStamped: no header"),
    ('{"header": 7, "twist": {}}', "TwistStamped.header must be an object"),
    ('{"header": {}, "twist": [0.2, 0.0]}', "TwistStamped.twist must be a geometry_msgs/Twist object"),
])
def test_a_rosbridge_twist_that_cannot_be_judged_is_a_clear_error(text, message):
    with pytest.raises(ValueError, match=message):
        Twist.from_ros(json.loads(text))


def test_a_twist_refuses_bools_and_numbers_too_large_for_a_float():
    with pytest.raises(ValueError, match="Twist.linear_x must be a number, got True"):
        Twist(True, 0.0)
    with pytest.raises(ValueError, match="Twist.angular_z must be a number, got an integer of 1329 bits"):
        Twist(0.1, 10**400)


@pytest.mark.parametrize("value", ["1_0", "1", " 1 ", "inf", b"1", bytearray(b"1"), True, False, np.bool_(True),
                                  [1.0], np.array([1.0]), None, {}, 1j])
def test_a_twist_reads_no_text_bool_or_container_as_a_number(value):
    """Issue 52 item 14: ``Twist("1_0", 0)`` was 10 m/s, ``Twist(True, 0)`` 1 m/s."""
    for fields in ({"linear_x": value, "angular_z": 0.0}, {"linear_x": 0.0, "angular_z": value},
                   {"linear_x": 0.0, "angular_z": 0.0, "linear_y": value}):
        with pytest.raises(ValueError, match="must be a number"):
            Twist(**fields)
    decoded = SimpleNamespace(linear=SimpleNamespace(x=value, y=0.0, z=0.0),
                              angular=SimpleNamespace(x=0.0, y=0.0, z=0.0))
    with pytest.raises(ValueError, match="Twist.linear.x must be a number"):
        Twist.from_ros(decoded)


def test_a_twist_reads_every_kind_of_real_number():
    from decimal import Decimal
    from fractions import Fraction

    twist = Twist(np.float32(0.5), Fraction(1, 4), Decimal("0.125"))
    assert (twist.linear_x, twist.angular_z, twist.linear_y) == (0.5, 0.25, 0.125)
    assert Twist(np.int64(1), 0).linear_x == 1.0 and type(Twist(np.int64(1), 0).linear_x) is float
