"""The Guard's inputs as declared types (``safeembodai_core.guard.inputs``): the same sensor keywords on every
judging method, each passed on, read once, and bad values refused with the keyword named."""

from __future__ import annotations

import inspect
import typing

import numpy as np
import pytest

from safeembodai_core import Guard, GuardReport
from safeembodai_core.guard.inputs import SENSOR_KEYWORDS, Sensing
from safeembodai_core.models import Pose, Straight, Turn
from safeembodai_core.ros import Twist

JUDGING = ("check", "check_twist", "limit_twist", "check_reply", "check_answer")
FORWARD = [{"command": "straight", "direction": "forward", "distance": 300}]
ANSWER = ('{"perception": [], "planning": "go on", '
          '"control": [{"command": "straight", "direction": "forward", "distance": 300}]}')
#: a wall 250 mm ahead of the robot, open everywhere else
WALL_AHEAD = np.full(360, np.inf)
WALL_AHEAD[[358, 359, 0, 1, 2]] = 250.0


@pytest.mark.parametrize("method", JUDGING)
def test_every_judging_method_takes_the_same_sensor_keywords_with_the_same_defaults(method):
    parameters = inspect.signature(getattr(Guard, method)).parameters
    for name, default in SENSOR_KEYWORDS.items():
        assert name in parameters, f"Guard.{method} has no {name}"
        assert parameters[name].kind is inspect.Parameter.KEYWORD_ONLY
        assert parameters[name].default == default, (method, name)


def _judge(guard: Guard, method: str, **sensors):
    if method == "check":
        return guard.check(FORWARD, **sensors)
    if method == "check_twist":
        return guard.check_twist(Twist(0.3, 0.0), 1.0, **sensors)
    if method == "limit_twist":
        return guard.limit_twist(Twist(0.3, 0.0), 1.0, **sensors)
    if method == "check_reply":
        return guard.check_reply(ANSWER, **sensors)
    return guard.check_answer(ANSWER, finish_reason="stop", **sensors)


@pytest.mark.parametrize("method", JUDGING)
def test_every_judging_method_passes_answer_time_on(method):
    """An answer before its scan is refused by every method: the keyword reached the reading."""
    with pytest.raises(ValueError, match="answer_time_s"):
        _judge(Guard(), method, lidar_mm=WALL_AHEAD, time_s=5.0, answer_time_s=4.0)


@pytest.mark.parametrize("method", JUDGING)
def test_every_judging_method_passes_since_scan_on(method):
    """Turned half round since the scan, the wall is behind: the forward motion is judged from there."""
    blocked = _judge(Guard(), method, lidar_mm=WALL_AHEAD)
    turned = _judge(Guard(), method, lidar_mm=WALL_AHEAD, since_scan=(0.0, 0.0, 180.0))
    if method == "limit_twist":
        assert blocked.factor < 1.0 and turned.factor == 1.0
    else:
        assert not blocked.valid and turned.valid


@pytest.mark.parametrize("method", JUDGING)
def test_every_judging_method_passes_keep_scan_on(method):
    guard = Guard()
    _judge(guard, method, lidar_mm=WALL_AHEAD, pose=(0.0, 0.0, 0.0), time_s=1.0, keep_scan=False)
    assert len(guard.history) == 0
    _judge(guard, method, lidar_mm=WALL_AHEAD, pose=(0.0, 0.0, 0.0), time_s=1.0)
    assert len(guard.history) == 1


@pytest.mark.parametrize("pose", [Pose(x_mm=10.0, y_mm=-5.0, heading_deg=30.0),
                                  {"x_mm": 10.0, "y_mm": -5.0, "heading_deg": 30.0}, (10.0, -5.0, 30.0),
                                  np.array([10.0, -5.0, 30.0])])
def test_a_pose_in_any_declared_form_reads_the_same(pose):
    assert Sensing.read(pose=pose).pose == Pose(x_mm=10.0, y_mm=-5.0, heading_deg=30.0)


@pytest.mark.parametrize("keyword, value", [
    ("lidar_mm", [10**400] * 360),           # does not fit a float: refused, never read as inf
    ("lidar_mm", "8000 " * 360),
    ("lidar_mm", {"ranges": [1.0] * 360}),
    ("pose", "0 0 0"),
    ("pose", (0.0, 0.0)),
    ("pose", (0.0, float("nan"), 0.0)),
    ("since_scan", (10**400, 0.0, 0.0)),
    ("time_s", float("inf")),
    ("max_range_mm", float("nan")),
])
def test_a_bad_sensor_value_is_a_value_error_naming_its_keyword(keyword, value):
    sensors = {"lidar_mm": [1000.0] * 360, keyword: value}
    for method in JUDGING:
        with pytest.raises(ValueError, match=keyword):
            _judge(Guard(), method, **sensors)


def test_a_reports_signals_are_the_contracts_signal_types():
    assert typing.get_type_hints(GuardReport)["signals"] == list[Straight | Turn]
    report = Guard().check([*FORWARD, {"command": "turn", "direction": "left", "angle": 30}],
                           lidar_mm=[5000.0] * 360)
    assert [type(s) for s in report.signals] == [Straight, Turn]
