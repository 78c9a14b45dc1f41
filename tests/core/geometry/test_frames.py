"""Frames and pose advancing (``safeembodai_core.geometry.frames``), the one place each is computed: against
plain trigonometry written here, and each other's inverses."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from safeembodai_core.geometry import advance, compose, into_frame, out_of_frame, relative_pose

coordinate = st.floats(-1e5, 1e5, allow_nan=False)
heading = st.floats(-720.0, 720.0, allow_nan=False)
poses = st.tuples(coordinate, coordinate, heading)


def test_a_point_ahead_and_left_of_a_robot_facing_north():
    origin = (1000.0, 2000.0, 90.0)
    assert into_frame(np.array([[1000.0, 2500.0], [900.0, 2000.0]]), origin) == pytest.approx(
        np.array([[500.0, 0.0], [0.0, 100.0]]), abs=1e-9)
    assert out_of_frame(np.array([[500.0, 0.0]]), origin) == pytest.approx(np.array([[1000.0, 2500.0]]), abs=1e-9)


@given(poses, st.lists(st.tuples(coordinate, coordinate), min_size=1, max_size=8))
def test_into_and_out_of_a_frame_are_inverses(origin, points):
    points = np.array(points)
    assert out_of_frame(into_frame(points, origin), origin) == pytest.approx(points, abs=1e-6)


@given(poses, poses)
def test_compose_undoes_relative_pose(origin, pose):
    x, y, h = compose(origin, relative_pose(origin, pose))
    assert (x, y) == pytest.approx(pose[:2], abs=1e-6)
    assert math.isclose(((h - pose[2] + 180.0) % 360.0) - 180.0, 0.0, abs_tol=1e-6)
    assert -180.0 <= h < 180.0


def test_advance_drives_along_the_heading_then_turns_unwrapped():
    assert advance((0.0, 0.0, 90.0), 300.0) == pytest.approx((0.0, 300.0, 90.0), abs=1e-9)
    assert advance((0.0, 0.0, 0.0), -200.0) == pytest.approx((-200.0, 0.0, 0.0))
    assert advance((5.0, 6.0, 170.0), turn_deg=30.0) == (5.0, 6.0, 200.0)  # a plan's turns add up exactly
