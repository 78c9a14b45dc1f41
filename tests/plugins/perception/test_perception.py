"""The ``images`` and ``text`` perceptions, and reading their output back."""

from __future__ import annotations

import math

import numpy as np
import pytest

from backend_helpers import flatland_observation
from safeembodai_core.models import LidarScan, Observation
from safeembodai_plugins.perception.describe import (
    SECTORS,
    TargetSighting,
    describe_lidar,
    describe_target,
    parse_lidar_text,
    parse_target_text,
    sector_clearance,
    sector_clearance_from_points,
)
from safeembodai_plugins.perception.lidar_image import read_lidar_image


@pytest.mark.parametrize("bearing", [-22.0, -5.0, 12.0, 25.0])
def test_text_perception_gives_the_cans_side_bearing_and_size(built_plugins, bearing):
    _, observation = flatland_observation(built_plugins, seed=11, turn_to_can=bearing)
    texts = built_plugins.registry.build("perception", "text", {}).perceive(observation).texts
    sighting = parse_target_text(texts["camera_text"])
    assert sighting.seen
    assert abs(sighting.bearing_deg - bearing) < 2.0
    expected_height = 138.6 / observation.truth.target_distance_mm  # flatland's pinhole: focal * 120 mm / d / h
    assert abs(sighting.height_fraction - expected_height) < 0.02


def test_text_perception_says_when_the_can_is_not_visible(built_plugins):
    _, observation = flatland_observation(built_plugins, seed=11, turn_to_can=120.0)
    texts = built_plugins.registry.build("perception", "text", {}).perceive(observation).texts
    assert texts["camera_text"] == "Camera: the red can is not visible."
    assert parse_target_text(texts["camera_text"]) == TargetSighting(seen=False)


def test_min_target_pixels_decides_what_counts_as_seen(built_plugins):
    _, observation = flatland_observation(built_plugins, seed=11, turn_to_can=0.0)
    strict = built_plugins.registry.build("perception", "text", {"min_target_pixels": 100_000})
    assert "not visible" in strict.perceive(observation).texts["camera_text"]


def test_lidar_text_gives_the_nearest_obstacle_per_sector(built_plugins):
    _, observation = flatland_observation(built_plugins, seed=12, obstacles=3)
    texts = built_plugins.registry.build("perception", "text", {}).perceive(observation).texts
    parsed = parse_lidar_text(texts["lidar_text"])
    truth = sector_clearance(observation.lidar)
    assert list(parsed) == list(SECTORS)
    for name in SECTORS:
        assert parsed[name] == pytest.approx(truth[name], abs=6.0)  # printed to the centimetre


def test_lidar_text_marks_missing_and_clear_sectors():
    ranges = np.full(360, 1500.0)
    ranges[0:5] = np.nan       # front: a missing beam
    ranges[157:204] = np.inf   # back (157.5 to 202.5 deg): nothing within range
    clearance = sector_clearance(LidarScan(ranges_mm=ranges, max_range_mm=6000.0))
    text = describe_lidar(clearance)
    assert "front no reading" in text and "back clear" in text and "left 1.50 m" in text
    parsed = parse_lidar_text(text)
    assert math.isnan(parsed["front"]) and math.isinf(parsed["back"]) and parsed["left"] == 1500.0


def test_camera_text_round_trips():
    for sighting in (TargetSighting(True, 17.0, 0.12), TargetSighting(True, -3.0, 0.05),
                     TargetSighting(True, 0.2, 0.3)):
        back = parse_target_text(describe_target(sighting))
        assert back.seen and back.bearing_deg == pytest.approx(round(sighting.bearing_deg) if abs(sighting.bearing_deg)
                                                               >= 0.5 else 0.0)
        assert back.height_fraction == pytest.approx(round(sighting.height_fraction * 100) / 100)
    assert parse_target_text("nothing about a camera") is None


@pytest.mark.parametrize("options", [{}, {"lidar_image_px": 400, "lidar_image_range_mm": 3000.0}])
def test_the_lidar_picture_reads_back_to_the_scan(built_plugins, options):
    _, observation = flatland_observation(built_plugins, seed=13, obstacles=4)
    images = built_plugins.registry.build("perception", "images", options).perceive(observation).images
    picture = read_lidar_image(images["lidar_image"].data)
    range_mm = options.get("lidar_image_range_mm", 4000.0)
    assert picture.range_mm == pytest.approx(range_mm, rel=0.03)  # scale found from the 1 m rings
    seen = sector_clearance_from_points(picture.points_mm)
    truth = sector_clearance(observation.lidar)
    pixel = range_mm / (images["lidar_image"].width / 2)
    for name in SECTORS:
        if truth[name] < range_mm * 0.95:
            assert truth[name] - 4 * pixel <= seen[name] <= truth[name] + 2 * pixel, name


def test_images_perception_can_add_the_texts(built_plugins):
    _, observation = flatland_observation(built_plugins, seed=14)
    both = built_plugins.registry.build("perception", "images", {"with_text": True}).perceive(observation)
    assert set(both.images) == {"camera_image", "lidar_image"} and set(both.texts) == {"camera_text", "lidar_text"}
    only = built_plugins.registry.build("perception", "images", {}).perceive(Observation(camera=observation.camera))
    assert set(only.images) == {"camera_image"} and not only.texts
