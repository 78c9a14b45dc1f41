"""Labbot families: per-trial Labbot dynamics drawn from a documented family.

Without a family the Labbots move bit-for-bit as before (fixtures recorded with the code before
families existed); with one, the trial's kind and each Labbot's parameters come from the seed
alone, lie in their kind's ranges and are reported in ground truth; the tuning and held-out
families share no speed or wander; blind, sensing and stop-and-go Labbots behave as documented."""

from __future__ import annotations

import json
import math
from collections import Counter

import numpy as np
import pytest

from safeembodai_core.models import Outcome, Straight, Turn
from safeembodai_core.plugin.registry import ComponentOptionsError
from safeembodai_plugins.environments.pybullet_rooms.labbots import TICK_S, LabbotSwarm
from safeembodai_plugins.environments.pybullet_rooms.movers import (
    FAMILIES, MIXED, Mover, MoverFamily, disjoint, family, world_report,
)
from safeembodai_plugins.environments.pybullet_rooms.options import DOOptions

#: issue 53's families beyond every other (the diagnosis family and the one held out from it)
FAR = ("far_tuning", "far")

#: Small, cheap observations: the camera and LiDAR do not matter here.
CHEAP = {"camera_width": 16, "camera_height": 12, "lidar_beams": 36}


def _one_kind(**kind) -> dict:
    """An inline family of one kind (fixed speed and wander unless given)."""
    return {"name": "test", "kinds": [{"name": "only", "speed_mm_s": [150, 150], "wander_deg": [0, 0], **kind}]}


# -- without a family: bit-for-bit as before -------------------------------------------------------

def _swarm_after_30_s(**options) -> LabbotSwarm:
    o = DOOptions(labbots=4, **options)
    xy = [[600.0, 600.0], [2000.0, 1000.0], [3300.0, 2500.0], [1200.0, 3200.0]]
    swarm = LabbotSwarm(o, np.array(xy), np.array([10.0, 100.0, -120.0, 45.0]),
                        np.array([[2000.0, 2000.0, 110.0]]), seed=2024)
    swarm.advance(30.0, np.array([2400.0, 1800.0]))
    return swarm


# recorded with labbots.py as it was before per-Labbot parameters (rounded to 1e-6 mm / deg)
BEFORE_SWARM = {
    "blind": ({"labbot_sensing": False},
              [1055.736821, 2048.64978, 358.013553, 185.675643, 3246.224214, 295.905573, 2581.467218, 2225.903282],
              [38.63817, -164.364304, 153.62361, 125.008704]),
    "yielding": ({"labbot_sensing": False, "labbots_avoid_robot": True, "labbot_wander_deg": 60.0},
                 [1204.779087, 354.778635, 2333.586048, 2492.432619, 2884.526279, 1839.659652, 1452.31532, 3777.436771],
                 [-48.182749, 96.743781, -123.267961, -166.724643]),
}
BEFORE_ROOM = {
    "sensing": ({"think_time_s": 2.0},
                [400.059357, 1416.295661, 1575.349161, 1126.804475, 2547.159301, 1946.571207],
                [116.300908, 49.071457, 169.890953]),
    "blind": ({"think_time_s": 2.0, "labbot_sensing": False},
              [598.084577, 294.197574, 919.319301, 254.615263, 2158.799313, 2773.520398],
              [-107.116713, -81.229993, 126.642785]),
}
FOUR_COMMANDS = [Turn(command="turn", direction="left", angle=40.0),
                 Straight(command="straight", direction="forward", distance=300.0)] * 2


@pytest.mark.parametrize("name", sorted(BEFORE_SWARM))
def test_a_swarm_without_a_family_moves_as_before(name):
    options, xy, heading = BEFORE_SWARM[name]
    swarm = _swarm_after_30_s(**options)
    np.testing.assert_allclose(swarm.xy.ravel(), xy, rtol=0, atol=2e-6)
    np.testing.assert_allclose(swarm.heading, heading, rtol=0, atol=2e-6)


@pytest.mark.parametrize("name", sorted(BEFORE_ROOM))
def test_a_room_without_a_family_moves_its_labbots_as_before(make_env, name):
    options, xy, heading = BEFORE_ROOM[name]
    env = make_env("DO", **options)
    env.reset(5)
    for signal in FOUR_COMMANDS:
        env.execute(signal)
        truth = env.observe().truth
        assert "world" not in truth.extra  # a room without a family reports nothing new
    assert env.sim_time_s == pytest.approx(12.333333333333332, abs=1e-12)
    np.testing.assert_allclose(env.swarm.xy.ravel(), xy, rtol=0, atol=2e-6)
    np.testing.assert_allclose(env.swarm.heading, heading, rtol=0, atol=2e-6)


def test_the_shipped_family_moves_exactly_as_the_default_options(make_env):
    plain, shipped = make_env("DO", think_time_s=2.0), make_env("DO", think_time_s=2.0, labbot_family="shipped")
    plain.reset(5)
    first = shipped.reset(5)
    assert world_report(first.truth.extra)["kind"] == "shipped"
    for signal in FOUR_COMMANDS:
        assert plain.execute(signal) == shipped.execute(signal)
        a, b = plain.observe().truth, shipped.observe().truth
        assert {k: v for k, v in b.extra.items() if k not in ("world", "world_kind")} == a.extra
    assert np.stack(plain.swarm.track).tobytes() == np.stack(shipped.swarm.track).tobytes()


# -- the families ------------------------------------------------------------------------------

@pytest.mark.parametrize("held_out_name", ["held_out", "held_out_2", "held_out_3"])
def test_tuning_and_held_out_share_no_speed_or_wander(held_out_name):
    tuning, held_out = FAMILIES["tuning"], FAMILIES[held_out_name]
    assert disjoint(tuning, held_out) == []  # per kind and across kinds
    assert {k.name for k in tuning.kinds} == {k.name for k in held_out.kinds} >= {
        "cruise", "fast", "wandering", "blind", "stop_and_go", MIXED}
    for kind in tuning.plain:  # the same kind in the other family: disjoint ranges, the same behaviour
        other = held_out.kind(kind.name)
        for key in ("speed_mm_s", "wander_deg"):
            a, b = getattr(kind, key), getattr(other, key)
            assert a[1] < b[0] or b[1] < a[0], (kind.name, key, a, b)
        assert (kind.sensing, kind.yielding, kind.stop_and_go > 0) == (other.sensing, other.yielding,
                                                                        other.stop_and_go > 0)
    for name, fam in FAMILIES.items():  # the robot (200 mm/s) has a chance; the far families are beyond it
        assert all(kind.speed_mm_s[1] <= 450.0 for kind in fam.plain) == (name not in FAR), name
    assert disjoint(tuning, FAMILIES["shipped"])  # the check does find overlaps: tuning holds the shipped point
    shipped = FAMILIES["shipped"].kinds
    assert len(shipped) == 1 and shipped[0].speed_mm_s == (150.0, 150.0) and shipped[0].wander_deg == (25.0, 25.0)
    assert shipped[0].sensing and not shipped[0].yielding and shipped[0].stop_and_go == 0.0


def test_the_far_families_lie_beyond_every_other_family_and_apart_from_each_other():
    others = [fam for name, fam in FAMILIES.items() if name not in FAR and name != "shipped"]
    for name in FAR:
        far = FAMILIES[name]
        assert {k.name for k in far.kinds} == {k.name for k in FAMILIES["tuning"].kinds}
        for other in others + [FAMILIES[n] for n in FAR if n != name]:
            assert disjoint(far, other) == [] and disjoint(other, far) == [], (name, other.name)
        speeds = [k.speed_mm_s for k in far.plain]
        assert all(hi < 20.0 or lo > 450.0 for lo, hi in speeds)  # slower or faster than any other family
        assert any(hi < 20.0 for _, hi in speeds) and any(lo > 450.0 for lo, _ in speeds)
        assert all(k.wander_deg[0] > 170.0 for k in far.plain)  # wider than any other family's wander
        stops = [k for k in far.plain if k.stop_and_go > 0]
        assert stops and all(k.go_s[1] < 0.8 and k.stop_s[1] < 0.3 for k in stops)  # shorter phases than any
    for other in others:  # ... than any other family's (their shortest: held_out_2's go, held_out_3's stop)
        for kind in (k for k in other.plain if k.stop_and_go > 0):
            assert kind.go_s[0] >= 0.8 and kind.stop_s[0] >= 0.3, other.name
            assert kind.wander_deg[1] <= 170.0 and 20.0 <= kind.speed_mm_s[0]
        assert all(k.wander_deg[1] <= 170.0 and k.speed_mm_s[0] >= 20.0 and k.speed_mm_s[1] <= 450.0
                   for k in other.plain), other.name
    assert FAMILIES["far"].kind("fast").speed_mm_s[1] > 600.0  # past the learned rule's pairing speed


def test_the_third_held_out_family_shares_no_speed_or_wander_with_any_other():
    third = FAMILIES["held_out_3"]
    for name in ("tuning", "held_out", "held_out_2"):
        assert disjoint(third, FAMILIES[name]) == [], name  # per kind and across kinds
        assert disjoint(FAMILIES[name], third) == [], name


def test_the_families_behaviours():
    for name in ("tuning", "held_out", "held_out_2", "held_out_3", *FAR):
        kinds = {k.name: k for k in FAMILIES[name].plain}
        assert not kinds["blind"].sensing and not kinds["blind"].yielding
        assert kinds["stop_and_go"].stop_and_go == 1.0
        assert kinds["fast"].speed_mm_s[0] > kinds["cruise"].speed_mm_s[1]
        assert kinds["wandering"].wander_deg[0] > kinds["cruise"].wander_deg[1]
        assert all(k.stop_and_go == 0.0 for n, k in kinds.items() if n != "stop_and_go")


@pytest.mark.parametrize("name", ["tuning", "held_out", "held_out_2", "held_out_3", *FAR])
def test_drawn_parameters_lie_in_their_kinds_ranges(name):
    fam = FAMILIES[name]
    for seed in range(300):
        draw = fam.draw(seed, 5)
        assert draw.family == name and len(draw.movers) == 5
        if draw.kind != MIXED:
            assert {m.kind for m in draw.movers} == {draw.kind}
        for mover in draw.movers:
            kind = fam.kind(mover.kind)
            assert kind.name != MIXED
            assert kind.speed_mm_s[0] <= mover.speed_mm_s <= kind.speed_mm_s[1]
            assert kind.wander_deg[0] <= mover.wander_deg <= kind.wander_deg[1]
            assert (mover.sensing, mover.yielding) == (kind.sensing, kind.yielding)
            assert mover.stop_and_go == (kind.stop_and_go == 1.0)
            assert (mover.go_s, mover.stop_s) == (kind.go_s, kind.stop_s)


@pytest.mark.parametrize("name", ["tuning", "held_out", "held_out_2"])
def test_kinds_come_in_proportion_to_their_weights(name):
    fam = FAMILIES[name]
    counts = Counter(fam.draw(seed, 3).kind for seed in range(1200))
    total = sum(k.weight for k in fam.kinds)
    for kind in fam.kinds:
        expected = 1200 * kind.weight / total
        assert 0.75 * expected <= counts[kind.name] <= 1.25 * expected, (kind.name, counts)
    mixed = Counter(m.kind for seed in range(1200) for m in fam.draw(seed, 3).movers
                    if fam.draw(seed, 3).kind == MIXED)
    assert set(mixed) == {k.name for k in fam.plain}  # a mixed trial's Labbots draw every other kind


def test_weights_and_inline_families():
    fam = MoverFamily(name="mine", kinds=[
        {"name": "slow", "weight": 3, "speed_mm_s": [10, 20], "wander_deg": [0, 5]},
        {"name": "quick", "weight": 1, "speed_mm_s": [300, 300], "wander_deg": [0, 0], "sensing": False,
         "yielding": True},
        {"name": "never", "weight": 0, "speed_mm_s": [1, 1], "wander_deg": [0, 0]},
    ])
    counts = Counter(fam.draw(seed, 1).kind for seed in range(800))
    assert counts["never"] == 0 and 500 <= counts["slow"] <= 700 and counts["slow"] + counts["quick"] == 800
    quick = next(fam.draw(seed, 2) for seed in range(100) if fam.draw(seed, 2).kind == "quick")
    assert all(m.speed_mm_s == 300.0 and m.yielding and not m.sensing for m in quick.movers)
    assert family("held_out") is FAMILIES["held_out"] and family(fam) is fam
    assert family(fam.model_dump()) == fam  # a family dumps and reloads


def test_the_draw_depends_on_the_seed_alone_and_not_on_the_labbots_streams():
    fam = FAMILIES["tuning"]
    assert fam.draw(17, 4) == fam.draw(17, 4)
    assert fam.draw(17, 4).movers[:2] != fam.draw(18, 4).movers[:2]
    assert fam.draw(17, 6).movers[:4] == fam.draw(17, 4).movers  # a Labbot's draw does not depend on later ones


# -- in the room: ground truth, determinism ----------------------------------------------------

def test_the_room_reports_the_draw_in_every_observations_ground_truth(make_env, moves):
    env = make_env("MO", labbot_family="tuning", labbots=3, think_time_s=1.0, **CHEAP)
    observation = env.reset(3)
    text = observation.truth.extra["world"]
    assert isinstance(text, str)  # GroundTruth.extra holds scalars: the report is JSON text
    world = world_report(observation.truth.extra)
    assert world == json.loads(text) and list(world) == ["family", "kind", "movers"] and world["family"] == "tuning"
    assert world == FAMILIES["tuning"].draw(3, 3).report()
    assert world_report({"collided": False}) is None
    for mover in world["movers"]:
        assert set(mover) == {"kind", "speed_mm_s", "wander_deg", "sensing", "yielding", "stop_and_go"}
        assert mover["speed_mm_s"] == round(mover["speed_mm_s"], 1)
    env.execute(moves.rotate(30))
    assert world_report(env.observe().truth.extra) == world and world_report(env.truth().extra) == world
    np.testing.assert_allclose(env.swarm.speed, [m.speed_mm_s for m in FAMILIES["tuning"].draw(3, 3).movers])


def test_kinds_cover_the_family_over_fifty_seeds(make_env):
    env = make_env("DO", labbot_family="held_out", **CHEAP)
    kinds = Counter(world_report(env.reset(seed).truth.extra)["kind"] for seed in range(50))
    assert set(kinds) == {k.name for k in FAMILIES["held_out"].kinds}
    assert max(kinds.values()) <= 20  # six kinds of equal weight: about 8 each


def test_the_same_seed_gives_the_same_draw_and_tracks(make_env, moves):
    def run(env):
        truth = env.reset(21).truth
        for k in range(6):
            env.execute(moves.go(250.0) if k % 2 else moves.rotate(60.0))
            env.observe()
        return world_report(truth.extra), np.stack(env.swarm.track).tobytes(), env.pose()

    a = make_env("DO", labbot_family="tuning", think_time_s=1.5, labbots=4, **CHEAP)
    b = make_env("DO", labbot_family="tuning", think_time_s=1.5, labbots=4, **CHEAP)
    assert run(a) == run(b)
    other = world_report(a.reset(22).truth.extra)
    assert other != run(b)[0]


def test_the_layout_does_not_depend_on_the_family(make_env):
    plain, drawn = make_env("MO", **CHEAP), make_env("MO", labbot_family="held_out", **CHEAP)
    for seed in (1, 2):
        plain.reset(seed)
        drawn.reset(seed)
        assert np.array_equal(plain.swarm.xy, drawn.swarm.xy) and np.array_equal(plain.can_xy, drawn.can_xy)
        assert plain.pose() == drawn.pose()


# -- behaviour per Labbot ----------------------------------------------------------------------

def _charging(make_env, family: dict, distance: float = 700.0):
    """A DO room with one Labbot ``distance`` mm from the robot, heading at it; 10 s of think time next."""
    env = make_env("DO", labbots=1, think_time_s=10.0, labbot_family=family, **CHEAP)
    observation = env.reset(3)
    scan = observation.lidar
    beam = int(np.argmax(scan.ranges_mm))
    direction = math.radians(observation.pose.heading_deg + scan.angles_deg[beam])
    env.swarm.xy[0] = env.xy + distance * np.array([math.cos(direction), math.sin(direction)])
    env.swarm.heading[0] = math.degrees(direction) + 180.0
    env.scene.place_labbots(env.swarm.xy, env.swarm.heading)
    return env


def test_a_blind_labbot_of_a_family_strikes_the_standing_robot_and_a_sensing_one_stops(make_env, moves):
    blind = _charging(make_env, _one_kind(sensing=False))
    assert blind.swarm.sensing == [False] and blind.labbot_sensors is None  # no sensor rays built: none senses
    hit = blind.execute(moves.rotate(3))
    assert hit.collided and hit.collision == "struck" and hit.hit == "labbot"
    assert blind.outcome() is Outcome.INTERRUPTED

    sensing = _charging(make_env, _one_kind(sensing=True))
    assert sensing.swarm.sensing == [True]
    result = sensing.execute(moves.rotate(3))
    assert not result.collided and sensing.outcome() is None
    gap = math.hypot(*(sensing.swarm.xy[0] - sensing.xy)) - sensing.robot.radius_mm - 120.0
    assert gap >= sensing.options.labbot_sensor_range_mm - 10.0

    yielding = _charging(make_env, _one_kind(sensing=False, yielding=True))
    assert not yielding.execute(moves.rotate(3)).collided


def test_only_sensing_labbots_react_to_their_sensors():
    o = DOOptions(labbots=2)
    movers = [Mover("a", 100.0, 0.0, True, False, False, (1.0, 1.0), (1.0, 1.0)),
              Mover("b", 100.0, 0.0, False, False, False, (1.0, 1.0), (1.0, 1.0))]
    always_near = lambda xy, headings, robot: np.array([[50.0, np.inf, np.inf, 10.0, np.inf]] * len(xy))  # noqa: E731
    swarm = LabbotSwarm(o, np.array([[1000.0, 1000.0], [3000.0, 3000.0]]), np.array([0.0, 180.0]),
                        np.zeros((0, 3)), seed=1, sense=always_near, movers=movers)
    swarm.advance(1.0, np.array([200.0, 3800.0]))
    assert np.array_equal(swarm.xy[0], [1000.0, 1000.0])  # it sees something: turns on the spot
    assert swarm.xy[1][0] == pytest.approx(2900.0)  # blind: drives on at its own speed


def test_each_labbot_moves_at_its_own_speed_and_wander():
    o = DOOptions(labbots=2, room_mm=8000.0)
    movers = [Mover("a", 100.0, 0.0, False, False, False, (1.0, 1.0), (1.0, 1.0)),
              Mover("b", 300.0, 0.0, False, False, False, (1.0, 1.0), (1.0, 1.0))]
    swarm = LabbotSwarm(o, np.array([[2000.0, 2000.0], [2000.0, 5000.0]]), np.array([0.0, 0.0]),
                        np.zeros((0, 3)), seed=1, movers=movers)
    swarm.advance(2.0, np.array([7000.0, 7000.0]))
    np.testing.assert_allclose(swarm.xy, [[2200.0, 2000.0], [2600.0, 5000.0]], atol=1e-9)
    assert swarm.top_speed == 300.0


def _stop_and_go_swarm(count: int = 1, wander: float = 0.0, seed: int = 8) -> LabbotSwarm:
    o = DOOptions(labbots=count, room_mm=12_000.0)
    movers = [Mover("stop_and_go", 100.0, wander, False, False, True, (1.0, 2.0), (1.0, 2.0))] * count
    xy = np.array([[6000.0, 4000.0 + 1500.0 * i] for i in range(count)])
    return LabbotSwarm(o, xy, np.linspace(-150.0, 150.0, count), np.zeros((0, 3)), seed=seed, movers=movers)


def test_a_stop_and_go_labbot_stands_still_while_stopped_and_leaves_at_a_new_heading():
    swarm = _stop_and_go_swarm()
    robot = np.array([300.0, 300.0])
    states = [(swarm.stopped()[0], swarm.xy[0].copy(), float(swarm.heading[0]))]
    for _ in range(int(12.0 / TICK_S)):
        swarm.advance(TICK_S, robot)
        states.append((swarm.stopped()[0], swarm.xy[0].copy(), float(swarm.heading[0])))
    # states[k] = (stopped at tick k?, position and heading before tick k)
    stops = [k for k in range(len(states) - 1) if states[k][0]]
    assert stops and len(stops) < len(states) - 1  # it stops, and it goes
    for k in stops:
        assert np.array_equal(states[k + 1][1], states[k][1]) and states[k + 1][2] == states[k][2]
    leaves = [k for k in stops if not states[k + 1][0]]  # the last tick of each stop
    assert len(leaves) >= 2
    for k in leaves:
        before, after = states[k + 1][2], states[k + 2][2]  # heading while stopped, after the first tick on
        assert abs((after - before + 180.0) % 360.0 - 180.0) > 1.0  # a new heading
        assert math.hypot(*(states[k + 2][1] - states[k + 1][1])) == pytest.approx(100.0 * TICK_S)
    go = [k for k in range(len(states) - 1) if not states[k][0]]
    assert all(math.hypot(*(states[k + 1][1] - states[k][1])) == pytest.approx(5.0) for k in go)
    lengths = np.diff([0] + [k + 1 for k in leaves])
    assert all(40 <= n <= 80 for n in lengths)  # a go (1-2 s) and a stop (1-2 s) per cycle, in ticks


def test_stop_and_go_is_a_function_of_simulated_time_only():
    robot = np.array([300.0, 300.0])
    whole = _stop_and_go_swarm(count=3, wander=20.0)
    whole.advance(12.0, robot)
    pieces = _stop_and_go_swarm(count=3, wander=20.0)
    rng = np.random.default_rng(0)
    spent = 0.0
    while spent < 12.0 - 0.2:
        dt = float(rng.uniform(0.001, 0.2))
        pieces.advance(dt, robot)
        spent += dt
    pieces.advance(12.0 - spent, robot)
    assert whole.ticks == pieces.ticks == 240
    assert whole.xy.tobytes() == pieces.xy.tobytes() and whole.heading.tobytes() == pieces.heading.tobytes()
    # and restoring a state (the world's contact checks do) replays the same stops
    saved = whole.state()
    whole.advance(3.0, robot)
    ahead = whole.xy.copy()
    whole.restore(saved)
    whole.advance(3.0, robot)
    assert np.array_equal(whole.xy, ahead)


def test_stop_and_go_labbots_in_a_room_do_not_depend_on_how_commands_are_split(make_env):
    family_ = _one_kind(sensing=False, stop_and_go=1.0, go_s=[0.5, 1.0], stop_s=[0.5, 1.0], wander_deg=[10, 30])

    def labbots_after(*angles):
        env = make_env("DO", labbot_family=family_, think_time_s=4.0, **CHEAP)
        env.reset(7)
        for angle in angles:
            env.execute(Turn(command="turn", direction="left", angle=angle))
        assert world_report(env.truth().extra)["movers"][0]["stop_and_go"] is True
        return env.sim_time_s, env.swarm.xy.tobytes(), env.swarm.heading.tobytes(), env.swarm.stopped()

    one, split = labbots_after(31.5), labbots_after(30.0, 1.5)
    assert one[0] == pytest.approx(split[0]) and one[1:] == split[1:]


# -- options -----------------------------------------------------------------------------------

@pytest.mark.parametrize("options, needles", [
    ({"labbot_family": "nope"}, ["labbot_family", "unknown Labbot family 'nope'", "held_out"]),
    ({"labbot_family": "tuning", "labbot_speed_mm_s": 300}, ["labbot_family", "labbot_speed_mm_s"]),
    ({"labbot_family": "held_out", "labbot_sensing": False, "labbots_avoid_robot": True},
     ["labbot_sensing", "labbots_avoid_robot"]),
    ({"labbot_family": {"kinds": [{"name": "x", "speed_mm_s": [300, 100], "wander_deg": [0, 1]}]}},
     ["labbot_family.kinds.0.speed_mm_s"]),
    ({"labbot_family": {"kinds": [{"name": "x", "speed_mm_s": [100, 300]}]}}, ["labbot_family", "wander_deg"]),
    ({"labbot_family": {"kinds": [{"name": "mixed"}]}}, ["labbot_family", "mixed"]),
    ({"labbot_family": {"kinds": [{"name": "x", "speed_mm_s": [1, 2], "wander_deg": [0, 1], "colour": 1}]}},
     ["labbot_family.kinds.0.colour"]),
    ({"labbot_family": {"kinds": [{"name": "mixed", "speed_mm_s": [1, 2]},
                                  {"name": "x", "speed_mm_s": [1, 2], "wander_deg": [0, 1]}]}},
     ["labbot_family", "speed_mm_s"]),
])
def test_bad_family_options_name_the_field(registry, options, needles):
    with pytest.raises(ComponentOptionsError) as caught:
        registry.validate_options("environment", "MO", options)
    for needle in needles:
        assert needle in str(caught.value)


def test_family_options(registry):
    assert registry.validate_options("environment", "DO", {}).labbot_family is None
    assert registry.validate_options("environment", "MO",
                                     {"labbot_family": "held_out"}).labbot_family.name == "held_out"
    inline = registry.validate_options("environment", "DO", {"labbot_family": _one_kind(sensing=False)})
    assert inline.labbot_family.name == "test" and not inline.labbot_family.kinds[0].sensing
    with pytest.raises(ComponentOptionsError, match="labbot_family"):
        registry.validate_options("environment", "SO", {"labbot_family": "tuning"})
