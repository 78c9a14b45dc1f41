"""``moving_obstacles`` learning its movers from the trial's scans, and judging where a plan leaves
the robot (issue 21): synthetic scans of a square room with discs, as in tests/support/mover_scenes.py.

* a mover faster than anything the rule assumes is seen as fast as its chords say;
* a mover followed over many scans keeps its own wander, one seen twice gets the prior;
* a mover that stopped and left again is fanned all the way round at its learned speed;
* histories of 1, 2 and many scans;
* a blind mover heading for a standing robot: the plan that parks the robot on its course is
  refused, the step aside it advises is accepted.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from safeembodai_core.models import Pose
from safeembodai_plugins.validators import MovingObstaclesOptions
from safeembodai_plugins.validators.moving.learning import LearningSettings, Track
from safeembodai_plugins.validators.moving import MovingObstaclesRule

from mover_scenes import ROBOT, THINK_S, go, history_context, refused, rotate
from mover_scenes import learned_rule as rule


def test_the_wander_estimate_pools_the_prior_with_the_movers_own_chords():
    s = LearningSettings(prior_wander_deg=45.0, prior_weight_s=4.0)
    straight = Track(speeds=(150.0,) * 6, headings=(0.3,) * 6, spans=(6.0,) * 6)
    assert straight.wander_deg(s) == pytest.approx(45.0 * math.sqrt(4.0 / 24.0))  # 20 s of straight chords, 4 of prior
    assert Track(speeds=(150.0,), headings=(0.3,), spans=(6.0,)).wander_deg(s) == pytest.approx(45.0)
    zigzag = Track(speeds=(150.0,) * 6, headings=(0.0, 2.0, 0.0, 2.0, 0.0, 2.0), spans=(6.0,) * 6)
    assert zigzag.wander_deg(s) > 45.0  # 2 rad between 6 s chords: about 57 deg per sqrt(s)
    # a stop (a chord shorter than still_mm) says nothing of the heading
    stopped = Track(speeds=(150.0, 5.0, 150.0), headings=(0.0, 3.0, 1.5), spans=(6.0,) * 3)
    assert stopped.wander_deg(s) == pytest.approx(45.0)
    # the cruising speed: the fastest chord, or the latest over its wandering chord share
    assert Track(speeds=(100.0, 300.0), headings=(0.0, 0.0), spans=(6.0, 6.0)).cruise_mm_s(20.0, s) >= 300.0


@pytest.mark.parametrize("scans", [2, 3])
def test_a_mover_faster_than_any_assumption_is_seen_as_fast_as_its_chords(scans):
    """A Labbot at 450 mm/s coming head-on along the robot's line (the shipped options assumed 150
    and paired nothing faster than 300): learned, its courses meet the robot's straight."""
    speed, dt = 450.0, 1.2
    positions = [(4600.0 + speed * dt * (scans - 1 - i), ROBOT.y_mm) for i in range(scans)]
    context = history_context(ROBOT, positions, dt)
    learned = rule(max_obstacle_speed_mm_s=1000.0)
    [blob], _ = learned.movers(context)
    assert blob.velocity is not None and math.hypot(*blob.velocity) == pytest.approx(speed, rel=0.15)
    assert blob.cruise_mm_s >= 0.85 * speed and blob.chords == scans - 1
    plan = [go(390), go(390), go(390)]
    assert refused(plan, context, learned)
    told = rule(history_scans=0, cruise_speed_mm_s=150.0, max_obstacle_speed_mm_s=300.0, wander_deg=25.0)
    [told_blob], _ = told.movers(context)
    assert told_blob.velocity is None  # too fast to pair for the told rule: fanned at 150 mm/s
    assert not refused(plan, context, told)


def test_a_single_scan_teaches_nothing_and_two_give_the_prior():
    one = history_context(ROBOT, [(3000.0, 5000.0)])
    assert rule().movers(one)[0] == []  # seen once: static
    two = history_context(ROBOT, [(3000.0, 5800.0), (3000.0, 5000.0)])
    [blob], _ = rule().movers(two)
    assert blob.chords == 1 and blob.wander_deg == pytest.approx(45.0)


def test_a_mover_that_stopped_and_left_again_is_fanned_all_the_way_round():
    """Cruising at 200 mm/s, then stopped, now moving off slowly: its latest chord is short of its
    cruising speed, so most of its courses start on a heading drawn all the way round."""
    positions = [(3000.0, 1000.0), (3000.0, 2200.0), (3000.0, 2200.0), (3000.0, 2500.0)]
    context = history_context(Pose(x_mm=1000.0, y_mm=4500.0, heading_deg=0.0), positions)
    learned = rule()
    [blob], _ = learned.movers(context)
    assert blob.cruise_mm_s >= 180.0 and blob.chords == 3  # followed through the stop
    assert learned.futures.turned_share(blob) > 0.2  # some of its courses leave on any heading


def _plan(advice: str):
    """``turn left 60 deg, then straight forward 390 mm`` as signals."""
    signals = []
    for step in advice.split(", then "):
        words = step.split()
        if words[0] == "turn":
            signals.append(rotate(float(words[2]) * (1 if words[1] == "left" else -1)))
        else:
            signals.append(go(float(words[2]) * (1 if words[1] == "forward" else -1)))
    return signals


def test_a_blind_mover_heading_for_a_standing_robot_refuses_the_plan_that_parks_on_its_course():
    """A Labbot coming head-on along the robot's line at 200 mm/s, 3 m ahead: a plan that only turns
    (waits) leaves the robot on its course and is refused with a step aside; the step aside passes.
    2 m ahead it would arrive while the robot still steps aside: no plan is safer, none is refused."""
    positions = [(4000.0 + 800.0 * k, ROBOT.y_mm) for k in (2, 1, 0)]
    context = history_context(ROBOT, positions, dt_s=4.0)
    parking = rule(park_check=True)
    reasons = refused([rotate(10)], context, parking)
    assert reasons and "step out of a moving obstacle's way" in reasons[0] and "on its course" in reasons[0]
    aside = _plan(reasons[0].split("for example ")[1].split(". ")[0])
    assert aside[0].command == "turn"  # backing away along its line would not do: it is stepped aside from
    assert not refused(aside, context, parking)
    assert not refused([rotate(10)], context, rule())  # off: where a plan leaves the robot is not judged
    too_late = history_context(ROBOT, [(3000.0 + 1200.0 * k, ROBOT.y_mm) for k in (2, 1, 0)])
    assert not refused([rotate(10)], too_late, parking)


def test_no_step_aside_is_advised_against_a_mover_that_arrives_during_the_think_time():
    """A Labbot at 250 mm/s, 1.2 m ahead on the robot's line, reaches the robot about 3.5 s after
    the scan: while the LLM still thinks, the robot stands there whatever the plan, so no plan is
    safer and a plan that waits is not refused (it was, with a turn-and-go step aside that cannot
    start before the mover arrives)."""
    positions = [(ROBOT.x_mm + 1200.0 + 1000.0 * k, ROBOT.y_mm) for k in (2, 1, 0)]
    context = history_context(ROBOT, positions, dt_s=4.0)
    parking = rule(park_check=True, max_obstacle_speed_mm_s=2000)
    blobs, think = parking.movers(context)
    spot = np.array([ROBOT.x_mm, ROBOT.y_mm])
    assert parking.parked_on(spot, context.robot.radius_mm, blobs, 0.0, think) is not None
    assert parking._step_aside(context, blobs, think, think) is None
    assert not refused([rotate(10)], context, parking)


def test_a_mover_arriving_while_the_robot_still_turns_on_its_spot_counts_as_parking():
    """The robot stands on its spot from the end of the plan's last straight -- for a plan of turns,
    from the scan on. A fast Labbot (about 410 mm/s, 3.5 m ahead) reaches the spot about 7 s after
    the scan and is past it before 9.4 s: a plan of three 89-degree turns (5 to 9.45 s after the scan)
    is struck while it turns, so it is refused, though the spot is clear again when it ends."""
    positions = [(ROBOT.x_mm + 3520.0 + 800.0 * k, ROBOT.y_mm) for k in (2, 1, 0)]
    context = history_context(ROBOT, positions, dt_s=2.0)
    parking = rule(park_check=True, max_obstacle_speed_mm_s=2000)
    reasons = refused([rotate(89)] * 3, context, parking)
    assert reasons and "step out of a moving obstacle's way" in reasons[0]
    blobs, think = parking.movers(context)
    spot = np.array([ROBOT.x_mm, ROBOT.y_mm])
    robot_mm = context.robot.radius_mm
    assert parking.parked_on(spot, robot_mm, blobs, THINK_S + 3 * 89 / 60, 20.0) is None  # clear at the end
    assert parking.parked_on(spot, robot_mm, blobs, THINK_S, 20.0) is not None  # struck while turning
    assert not refused([rotate(89)] * 3, context, rule(max_obstacle_speed_mm_s=2000))

def test_the_shipped_options_of_the_moving_arm_name_nothing_of_the_labbots():
    """Issue 21: scenarios/movers.yaml's moving arm is told no cruise speed, no yielding, no top speed
    of the rooms' Labbots; it learns them, or assumes its own priors."""
    import yaml

    from safeembodai_core.trust.world_private import private_fields

    scenario = yaml.safe_load((Path(__file__).resolve().parents[4] / "scenarios" / "movers.yaml").read_text())
    [rule_ref] = [v for v in scenario["arms"]["moving"]["validators"] if isinstance(v, dict)]
    options = rule_ref.get("options", {})
    assert not private_fields(MovingObstaclesOptions) & set(options)  # declared world-private (issue 39)
    assert options.get("history_scans", 0) > 0
    assert MovingObstaclesOptions(**options).think_time_s is None  # estimated, not told



def _reachable(value, seen=None):
    """Every object reachable from ``value`` through dataclass fields, pydantic fields and containers."""
    import dataclasses

    import numpy as np
    from pydantic import BaseModel

    seen = set() if seen is None else seen
    if id(value) in seen:
        return
    seen.add(id(value))
    yield value
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        children = [getattr(value, f.name) for f in dataclasses.fields(value)]
    elif isinstance(value, BaseModel):
        children = [getattr(value, name) for name in type(value).model_fields]
    elif isinstance(value, dict):
        children = [*value.keys(), *value.values()]
    elif isinstance(value, (list, tuple, set, frozenset)):
        children = list(value)
    elif isinstance(value, np.ndarray) and value.dtype == object:
        children = list(value.ravel())
    else:
        children = []
    for child in children:
        yield from _reachable(child, seen)


def test_the_rule_reads_nothing_a_world_keeps_private(plugins, repo, monkeypatch, cell):
    """Issue 21: in a real trial of scenarios/movers.yaml's moving arm, everything handed to
    ``moving_obstacles`` (its options and every ValidationContext) is made of the core's records,
    numbers, strings and arrays -- no object of the environment's (its Labbots, its world report, its
    ground truth) and no text naming them -- and the rule's modules import nothing of the
    environments: what it knows of the movers it has from the scans."""
    import ast

    import numpy as np

    from safeembodai_core.scenario import load_scenario

    sources = sorted((repo / "plugins" / "validators").rglob("*.py"))
    assert {"moving/__init__.py", "moving/moving_obstacles.py", "moving/learning.py", "moving/futures.py",
            "moving/tracking.py"} <= {
        p.relative_to(repo / "plugins" / "validators").as_posix() for p in sources}
    for module in sources:
        tree = ast.parse(module.read_text())
        imported = [n.module or "" for n in ast.walk(tree) if isinstance(n, ast.ImportFrom)] + \
            [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
        assert not [name for name in imported if "environments" in name or "pybullet" in name], module

    handed: list = []
    original = MovingObstaclesRule.validate

    def spy(self, signal, context):
        handed.append((self.options, context))
        return original(self, signal, context)

    monkeypatch.setattr(MovingObstaclesRule, "validate", spy)
    scenario = load_scenario(str(repo / "scenarios" / "movers.yaml"),
                             ["trials=1", "max_steps=4", "environments.0.options.labbot_family=tuning", "state=memory"],
                             plugins.registry)
    _, steps, _ = cell(scenario, "moving", "no_attack", plugins=plugins)
    assert len(handed) >= 2 and any(context.history for _, context in handed), "the rule never saw a history"
    assert "world" in steps[0].truth.extra  # the world is drawn and reported -- to the record, not the rule
    allowed = ("safeembodai_core.", "numpy", "builtins", "safeembodai_plugins.validators")
    for options, context in handed:
        for value in _reachable((options, context)):
            module = type(value).__module__
            assert module.startswith(allowed) or isinstance(value, np.generic), (module, type(value))
            if isinstance(value, str):
                assert "labbot" not in value.lower() and "world" not in value.lower(), value
