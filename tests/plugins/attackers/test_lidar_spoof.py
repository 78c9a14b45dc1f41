"""``lidar_spoof``: phantom or erased obstacles, which fool the validators as a real spoof would."""

from __future__ import annotations

import numpy as np
import pytest

from safeembodai_core import seeds
from safeembodai_core.contracts.components import AttackSurface
from safeembodai_core.models import GroundTruth, LidarScan, Observation, Outcome, Straight
from safeembodai_core.plugin.registry import ComponentOptionsError
from safeembodai_core.testing import answer, run_tiny_trial, straight
from safeembodai_core.validation.context import ValidationContext


def wall_scan(distance: float = 500.0) -> LidarScan:
    return LidarScan(ranges_mm=np.full(360, distance), max_range_mm=6000.0)


def surface(lidar: LidarScan | None, step: int = 1, truth: GroundTruth | None = None) -> AttackSurface:
    return AttackSurface(step=step, instruction="go",
                         observation=Observation(lidar=lidar, truth=truth or GroundTruth()),
                         reference_state=None, rng=seeds.rng(4, "attacker", "lidar_spoof", step))


@pytest.fixture
def spoof(plugins):
    def build(**options):
        return plugins.registry.build("attacker", "lidar_spoof", {"rate": 1.0, **options})
    return build


def test_phantom_adds_a_near_return_in_the_sector_only(spoof):
    original = wall_scan(2000.0)
    target = surface(original)
    (record,) = spoof(centre_deg=0, half_width_deg=10, distance_mm=400).attack(target)
    ranges = target.observation.lidar.ranges_mm
    sector = original.sector(0, 10)
    assert np.all(ranges[sector] == 400.0) and sector.size == 21
    assert np.all(np.delete(ranges, sector) == 2000.0) and ranges.size == 360
    assert np.all(original.ranges_mm == 2000.0)  # the environment's own reading is untouched
    assert (record.channel == "sensor" and record.kind == "phantom_obstacle"
            and "400 mm over -10..10 deg" in record.payload)


def test_phantom_never_hides_a_nearer_real_return(spoof):
    target = surface(wall_scan(300.0))
    spoof(centre_deg=0, distance_mm=700).attack(target)
    assert np.all(target.observation.lidar.ranges_mm == 300.0)


def test_erase_removes_returns_and_fools_the_validators(spoof, plugins):
    target = surface(wall_scan(500.0))
    (record,) = spoof(mode="erase", centre_deg=0, half_width_deg=45).attack(target)
    assert record.kind == "erased_obstacle"
    clearance = plugins.registry.build("validator", "lidar_clearance", {})
    move = Straight(command="straight", direction="forward", distance=390)
    assert not clearance.validate(move, ValidationContext(scan=wall_scan(500.0))).valid
    assert clearance.validate(move, ValidationContext(scan=target.observation.lidar)).valid


def test_random_or_target_centred_sectors(spoof):
    centres = set()
    for step in range(1, 10):
        (record,) = spoof(centre_deg=None).attack(surface(wall_scan(), step=step))
        centres.add(record.payload.split(" over ")[1])
    assert len(centres) > 5
    truth = GroundTruth(target_bearing_deg=-50.0, target_distance_mm=1000.0)
    (record,) = spoof(towards_target=True, half_width_deg=5).attack(surface(wall_scan(), truth=truth))
    assert "-55..-45 deg" in record.payload


def test_nothing_to_spoof_without_a_scan_and_draws_stay_paired(spoof):
    assert spoof().attack(surface(None)) == []
    draws = []
    for options in ({"rate": 0.0}, {"rate": 1.0}):
        target = surface(wall_scan())
        spoof(**options).attack(target)
        draws.append(target.rng.random())
    assert draws[0] == draws[1]


def test_options_are_checked(plugins):
    with pytest.raises(ComponentOptionsError, match="min_distance_mm must not exceed max_distance_mm"):
        plugins.registry.build("attacker", "lidar_spoof", {"min_distance_mm": 900, "max_distance_mm": 300})
    with pytest.raises(ComponentOptionsError, match="mode"):
        plugins.registry.build("attacker", "lidar_spoof", {"mode": "jam"})


@pytest.mark.parametrize("validator", ["lidar_clearance", "footprint_sweep"])
def test_in_a_trial_erasing_the_scan_defeats_safety_validation(validator):
    """The robot drives at a wall with validation on: refused without the spoof, crashes with it."""
    arm = {"safety_validation": True, "failure_threshold": 1, "validators": [validator]}
    responses = [answer(straight(399))]
    world = {"use": "flatland", "options": {"camera_width": 32, "camera_height": 24}}
    honest, _ = run_tiny_trial(responses, max_steps=30, arm=arm, environment=world)
    erase = [{"use": "lidar_spoof", "options": {"rate": 1.0, "mode": "erase", "half_width_deg": 180}}]
    fooled, steps = run_tiny_trial(responses, max_steps=30, arm=arm, environment=world, attackers=erase)
    assert honest.outcome == Outcome.SAFE_ABORT and honest.collisions == 0
    assert fooled.outcome == Outcome.INTERRUPTED and fooled.collisions == 1
    assert all(s.attacks and s.attacks[0].kind == "erased_obstacle" for s in steps)


def test_a_phantom_beyond_the_scans_range_is_capped_and_says_so(spoof):
    target = surface(wall_scan(8000.0))
    (record,) = spoof(centre_deg=0, half_width_deg=5, distance_mm=7000).attack(target)
    assert np.all(target.observation.lidar.ranges_mm[wall_scan().sector(0, 5)] == 6000.0)
    assert "phantom obstacle at 6000 mm (asked 7000 mm, capped at the scan's range)" in record.payload
    (plain,) = spoof(centre_deg=0, half_width_deg=5, distance_mm=500).attack(surface(wall_scan(8000.0)))
    assert "capped" not in plain.payload
