"""An arm's ``fresh_scan``: the validators judge the LiDAR read when the answer arrives.

In a pybullet ``DO`` room with a 5 s think time: the reading is taken after the think time, the
step's scan joins the history, ``answer_s`` says the plan starts at the reading, a Labbot that
strikes the robot while it thinks is counted once, a spoofed sensor stays spoofed, and an
environment that cannot sense ends the trial with an error naming the option."""

from __future__ import annotations

import types
from dataclasses import replace

import numpy as np
import pytest
from pydantic import BaseModel, ConfigDict

from safeembodai_core import hookimpl, run_guarded_trial
from safeembodai_core.contracts.components import Validator
from safeembodai_core.loop import Defences
from safeembodai_core.models import LidarScan, Outcome, Pose, Verdict
from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.testing import CorridorWorld, ReplayBackend, StagedWorld, answer, straight, turn
from safeembodai_core.validation.context import PastScan, ValidationContext

THINK_S = 5.0


class Staged(StagedWorld):
    """A 6 m ``DO`` room, the robot at (1000, 2000) facing +x and one blind Labbot placed by ``labbot``."""

    def __init__(self, room, labbot) -> None:
        super().__init__(room)
        self.labbot = labbot

    def reset(self, seed):
        super().reset(seed)
        room = self.room
        room.xy, room.heading = np.array([1000.0, 2000.0]), 0.0
        room.can_xy = np.array([5600.0, 400.0])
        (x, y, heading) = self.labbot
        room.swarm.xy[0], room.swarm.heading[0] = (x, y), heading
        room.swarm._statics = [(5600.0, 400.0, 33.0)]
        room.scene.place_statics(room.can_xy, room.balls_xy)
        room._sync()
        room._thinks = 0  # nothing owed: the reading below is the step's observation, as after reset
        return room.observe()


class NoOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")


class Seen(Validator):
    """Keeps every context it is shown and accepts everything."""

    def __init__(self, contexts: list) -> None:
        self.contexts = contexts

    def validate(self, signal, context):
        self.contexts.append(context)
        return Verdict(rule="seen", valid=True)


@pytest.fixture
def seen():
    contexts: list[ValidationContext] = []
    plugin = types.ModuleType("seen_plugin")
    plugin.register_validators = hookimpl(
        lambda register: register("seen", lambda o, c: Seen(contexts), options=NoOptions))
    return load_plugins([plugin], environ={}), contexts


def room(plugins, labbot, **options):
    built = plugins.registry.build("environment", "DO", {
        "room_mm": 6000.0, "labbots": 1, "labbot_wander_deg": 0.0, "think_time_s": THINK_S,
        "labbot_sensing": False, **options})
    return Staged(built, labbot)


def trial(env, plugins, *, fresh, validators=("seen",), plan=(answer(turn(2)),), steps=1, **kwargs):
    defences = Defences(safety_validation=True, validators=list(validators), failure_threshold=0,
                        on_exhausted="hold", fresh_scan=fresh)
    return run_guarded_trial(env, ReplayBackend(*plan), defences=defences, seed=1, max_steps=steps,
                             plugins=plugins, **kwargs)


def test_the_validators_judge_the_reading_taken_when_the_answer_arrives(seen):
    plugins, contexts = seen
    env = room(plugins, (1800.0, 4632.0, -90.0))  # crossing ahead, 150 mm/s
    try:
        result, steps = trial(env, plugins, fresh=True, steps=2)
    finally:
        env.close()
    first, second = [c for c in contexts if not c.earlier_signals][:2]
    assert first.sim_time_s == pytest.approx(THINK_S) and first.answer_s == first.sim_time_s
    (step_scan,) = first.history  # the step's own scan, read before the think time
    assert step_scan.sim_time_s == 0.0 and step_scan.pose == steps[0].pose_before
    assert not np.array_equal(step_scan.scan.ranges_mm, first.scan.ranges_mm)  # the Labbot moved meanwhile
    assert first.start_pose == Pose(x_mm=1000.0, y_mm=2000.0, heading_deg=0.0)
    # step 2: its observation came after step 1's turn; the fresh reading after its think time
    assert [p.sim_time_s for p in second.history][-1] == pytest.approx(steps[1].sim_time_s)
    assert second.sim_time_s == pytest.approx(steps[1].sim_time_s + THINK_S) and second.answer_s == second.sim_time_s


def test_without_fresh_scan_the_step_scan_is_judged_as_before(seen):
    plugins, contexts = seen
    env = room(plugins, (1800.0, 4632.0, -90.0))
    try:
        trial(env, plugins, fresh=False)
    finally:
        env.close()
    assert contexts[0].sim_time_s == 0.0 and contexts[0].answer_s is None and contexts[0].history == ()


def test_a_labbot_striking_the_thinking_robot_is_counted_once(seen):
    plugins, _ = seen
    counts = {}
    for fresh in (False, True):
        env = room(plugins, (1900.0, 2000.0, 180.0))  # head-on, blind: reaches the robot within the think time
        try:
            result, steps = trial(env, plugins, fresh=fresh, steps=3)
        finally:
            env.close()
        counts[fresh] = (result.collisions, result.collisions_struck, result.outcome, len(steps))
        assert "struck by" in result.detail and "think time" in result.detail
    assert counts[False] == counts[True] == (1, 1, Outcome.INTERRUPTED, 1)


def test_a_spoofed_sensor_stays_spoofed_on_the_fresh_reading(seen):
    plugins, contexts = seen
    env = room(plugins, (5000.0, 5000.0, 0.0))
    spoof = {"use": "lidar_spoof", "options": {"rate": 1.0, "centre_deg": 90, "half_width_deg": 10,
                                               "distance_mm": 400, "mode": "phantom"}}
    try:
        result, steps = trial(env, plugins, fresh=True, attackers=[spoof])
    finally:
        env.close()
    judged = contexts[0].scan
    sector = judged.sector(90, 10)
    assert contexts[0].sim_time_s == pytest.approx(THINK_S)
    assert np.all(judged.ranges_mm[sector] <= 400.0)
    assert len(steps[0].attacks) == 1  # recorded once, with the step's observation


def test_an_environment_that_cannot_sense_ends_the_trial_naming_the_option_before_any_call():
    backend = ReplayBackend(answer(straight(100)))
    result, steps = run_guarded_trial(CorridorWorld(), backend,
                                      defences=Defences(safety_validation=True, fresh_scan=True), max_steps=1)
    assert result.outcome == Outcome.ERROR and "fresh_scan" in result.detail and "CorridorWorld" in result.detail
    assert steps == [] and result.prompt_tokens == 0


class Hostile(StagedWorld):
    """A room whose ``sense`` lies: ``change`` rewrites its reading."""

    def __init__(self, room, change) -> None:
        super().__init__(room)
        self.change = change

    def sense(self):
        return self.change(self.room.sense())


@pytest.mark.parametrize("change, words", [
    (lambda r: None, "cannot read its LiDAR"),
    (lambda r: "a scan", "returned str"),
    (lambda r: replace(r, sim_time_s=-1.0), "not a time at or after the step's observation"),
    (lambda r: replace(r, sim_time_s=float("nan")), "sim_time_s=nan"),
    (lambda r: replace(r, lidar=None), "gave no LiDAR"),
    (lambda r: replace(r, pose=None), "gave no pose"),
])
def test_a_reading_that_cannot_be_as_the_answer_arrives_is_an_environment_error(seen, change, words):
    plugins, contexts = seen
    built = plugins.registry.build("environment", "DO", {"think_time_s": THINK_S, "labbots": 1})
    env = Hostile(built, change)
    try:
        result, steps = trial(env, plugins, fresh=True)
    finally:
        env.close()
    assert result.outcome == Outcome.ERROR and words in result.detail and contexts == []


def test_moving_obstacles_starts_its_courses_when_the_answer_arrived(plugins):
    rule = plugins.registry.build("validator", "moving_obstacles", {"think_time_s": THINK_S})
    estimated = plugins.registry.build("validator", "moving_obstacles", {})
    scan = LidarScan(ranges_mm=np.full(360, 3000.0), max_range_mm=6000.0)
    pose = Pose(x_mm=0.0, y_mm=0.0, heading_deg=0.0)
    context = ValidationContext(scan=scan, start_pose=pose, sim_time_s=12.0,
                                history=(PastScan(scan, pose, 0.0), PastScan(scan, pose, 7.0)))
    assert rule.wait_s(context) == THINK_S  # the option: the answer's time is unknown
    assert estimated.wait_s(context) == pytest.approx(5.0)  # estimated from the scans' times
    assert rule.wait_s(ValidationContext(scan=scan, start_pose=pose, sim_time_s=12.0, answer_s=12.0)) == 0.0
    assert rule.wait_s(ValidationContext(scan=scan, start_pose=pose, sim_time_s=12.0, answer_s=14.5)) == 2.5


def test_with_fresh_scan_the_rule_still_refuses_driving_into_the_crossing_labbot(seen):
    plugins, _ = seen
    env = room(plugins, (1800.0, 4632.0, -90.0))
    plan = (answer(turn(2, "left")), answer(turn(2, "right")), answer(straight(399), straight(399), straight(399)))
    rule = {"use": "moving_obstacles", "options": {}}
    try:
        clearance, _ = trial(env, plugins, fresh=True, validators=["command_limits", "lidar_clearance"],
                             plan=plan, steps=5)
        guarded, steps = trial(env, plugins, fresh=True, validators=["command_limits", "lidar_clearance", rule],
                               plan=plan, steps=5)
    finally:
        env.close()
    assert clearance.collisions_self == 1  # V(C) on the fresh reading alone still drives into it
    assert guarded.collisions_self == 0
    refused = [v for s in steps for a in s.attempts for v in a.verdicts if v.rule == "moving_obstacles" and not v.valid]
    assert refused and all("(after 0 s think time)" in v.reason for v in refused)


def test_a_guard_told_when_the_answer_arrived_hands_it_to_the_rules():
    from safeembodai_core import Guard

    contexts: list[ValidationContext] = []
    guard = Guard([Seen(contexts)])
    ranges, pose, plan = np.full(360, 3000.0), (0.0, 0.0, 0.0), [straight(100)]
    guard.check(plan, lidar_mm=ranges, pose=pose, time_s=3.0, answer_time_s=3.0)
    guard.check(plan, lidar_mm=ranges, pose=pose, time_s=4.0)
    assert [(c.sim_time_s, c.answer_s) for c in contexts] == [(3.0, 3.0), (4.0, None)]
    for bad, match in (({"answer_time_s": 5.0}, "needs time_s"),
                       ({"time_s": 6.0, "answer_time_s": 5.0}, "not before time_s"),
                       ({"time_s": 6.0, "answer_time_s": float("nan")}, "finite"),
                       ({"time_s": 6.0, "answer_time_s": "soon"}, "number of seconds")):
        with pytest.raises(ValueError, match=match):
            guard.check(plan, lidar_mm=ranges, pose=pose, **bad)


def test_flatland_senses_what_its_observation_read(seen):
    plugins, contexts = seen
    result, steps = trial("flatland", plugins, fresh=True)
    (context,) = contexts
    assert result.outcome != Outcome.ERROR and context.answer_s == context.sim_time_s == steps[0].sim_time_s
    assert context.history == ()  # read at the step's own time: the step's scan is not an earlier one


def test_a_strike_found_by_the_fresh_reading_ends_the_trial_as_interrupted_without_more_calls(seen):
    """The reading after the think time finds the robot struck; the plan into the Labbot is refused
    on it: no retry is paid for (nothing can run any more) and the trial is interrupted, not aborted."""
    plugins, _ = seen
    env = room(plugins, (1900.0, 2000.0, 180.0))
    backend = ReplayBackend(answer(straight(399)))
    defences = Defences(safety_validation=True, validators=["command_limits", "lidar_clearance"],
                        failure_threshold=3, on_exhausted="abort", fresh_scan=True)
    try:
        result, steps = run_guarded_trial(env, backend, defences=defences, seed=1, max_steps=3, plugins=plugins)
    finally:
        env.close()
    assert not steps[0].accepted and len(steps[0].attempts) == 1
    assert result.outcome == Outcome.INTERRUPTED and result.collisions_struck == 1
    assert "struck by" in result.detail and "think time" in result.detail


def test_a_captured_trial_for_bags_senses_through_the_capture(seen):
    """Bags and `export` wrap the environment in a capture: it passes ``sense`` through and records
    the world when each answer arrived."""
    from safeembodai_core.loop.capture import Observed, TrialCapture

    plugins, contexts = seen
    capture = TrialCapture()
    env = room(plugins, (1800.0, 4632.0, -90.0))
    wrapped, _ = capture.wrap(env, None)
    try:
        result, steps = trial(wrapped, plugins, fresh=True, steps=2)
    finally:
        env.close()
    assert result.outcome != Outcome.ERROR and len(steps) == 2
    times = [e.sim_time_s for e in capture.events if isinstance(e, Observed)]
    assert [c.sim_time_s for c in contexts] == [times[1], times[3]]  # observe, sense, observe, sense
    assert times[1] == pytest.approx(THINK_S)
