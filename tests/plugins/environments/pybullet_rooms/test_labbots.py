"""The Labbots' motion through think times and commands: the same trajectories as before the rooms'
cost cuts (commit 547552e), and the same as the rooms give with every shortcut turned off.

``TODAY`` was recorded at commit 547552e (before the cuts) with ``think_time_s: 5``: per command of
a fixed plan, the simulated time when it was observed, then every Labbot's position (mm), the
robot's pose and whether the command ended in a collision, once it had run. Positions must stay
within 1 mm (they are equal to the last bit today; the millimetre leaves room for another
platform's floating point).
"""

from __future__ import annotations

import numpy as np
import pytest

from safeembodai_core.models import Straight, Turn

PLAN = [Straight(command="straight", direction="forward", distance=300.0),
        Turn(command="turn", direction="left", angle=40.0),
        Straight(command="straight", direction="forward", distance=250.0),
        Turn(command="turn", direction="right", angle=75.0)] * 4

TODAY = {
    ('DO', 11): [
        (5.0, [[3237.8044, 1269.2417], [1539.5062, 2485.1812], [1779.8931, 1957.0164]],
         [918.7442, 2176.0419, 36.5394], False),
        (11.5, [[2861.961, 2008.588], [1585.9158, 1962.1378], [2237.895, 2501.4053]],
         [918.7442, 2176.0419, 76.5394], False),
        (17.166667, [[2194.9948, 2548.9434], [2350.1177, 1919.6274], [2590.1066, 3344.6994]],
         [976.9383, 2419.1744, 76.5394], False),
        (23.416667, [[1527.0843, 2133.0982], [3034.5926, 1390.244], [3164.326, 3356.7173]],
         [976.9383, 2419.1744, 1.5394], False),
        (29.666667, [[1763.5477, 1341.8955], [3599.1545, 948.5222], [3436.3161, 2789.2676]],
         [1276.83, 2427.2338, 1.5394], False),
        (36.166667, [[2296.2965, 769.6638], [3574.5981, 405.9427], [3549.9224, 2060.1972]],
         [1276.83, 2427.2338, 41.5394], False),
        (41.833333, [[2792.8465, 407.9633], [3284.049, 397.1584], [3539.8385, 1304.8449]],
         [1463.955, 2593.0175, 41.5394], False),
        (48.083333, [[2635.8213, 1128.9345], [3468.9421, 412.8356], [3601.1356, 1263.1146]],
         [1463.955, 2593.0175, -33.4606], False),
        (54.333333, [[2678.9, 1897.4932], [3505.645, 859.1577], [3367.034, 2043.5904]],
         [1714.2346, 2427.6085, -33.4606], False),
        (60.833333, [[2782.1697, 2584.0321], [2688.2029, 953.4803], [3083.7192, 2207.6134]],
         [1714.2346, 2427.6085, 6.5394], False),
        (66.5, [[3096.6363, 3426.4572], [1809.7273, 760.2442], [3572.7569, 2873.3937]],
         [1962.608, 2456.0802, 6.5394], False),
        (72.75, [[2608.1893, 3455.1425], [1223.8907, 1385.7253], [3524.8067, 3597.0441]],
         [1962.608, 2456.0802, -68.4606], False),
        (79.0, [[2767.7542, 2530.2188], [1561.9159, 2062.4747], [3599.7392, 3175.6481]],
         [2072.7503, 2177.0306, -68.4606], False),
        (85.5, [[2736.1777, 1728.9218], [1502.771, 2848.4235], [3558.4545, 2342.7491]],
         [2072.7503, 2177.0306, -28.4606], False),
        (91.166667, [[3483.5477, 1249.7577], [1075.2987, 3586.7918], [3594.3912, 1741.4964]],
         [2292.5366, 2057.8921, -28.4606], False),
        (97.416667, [[3590.3085, 1258.6417], [1165.8617, 3606.2939], [3369.8872, 1719.1678]],
         [2292.5366, 2057.8921, -28.4606], False),
    ],
    ('MO', 5): [
        (5.0, [[3279.746, 3603.4443], [3380.3957, 2635.3682]],
         [3384.4206, 3125.1126, 5.5172], False),
        (11.5, [[2582.0904, 3320.8855], [2572.3957, 2791.8926]],
         [3384.4206, 3125.1126, 45.5172], False),
        (17.166667, [[1807.1344, 3289.9239], [1844.7504, 2557.0046]],
         [3559.5944, 3303.4778, 45.5172], False),
        (23.416667, [[1191.843, 2634.8696], [1203.5935, 2092.0963]],
         [3559.5944, 3303.4778, -29.4828], False),
        (29.666667, [[1049.4915, 1930.2554], [401.8441, 2111.0012]],
         [3820.7454, 3155.8291, -29.4828], False),
        (36.166667, [[1099.1332, 1131.9409], [490.6634, 2842.157]],
         [3820.7454, 3155.8291, 10.5172], False),
        (41.833333, [[1423.4177, 565.5928], [743.6925, 3277.2071]],
         [3829.9629, 3157.5404, 10.5172], True),
    ],
}


def run_plan(env, seed: int) -> list:
    env.reset(seed)
    rows = []
    for signal in PLAN:
        observation = env.observe()
        result = env.execute(signal)
        rows.append((observation.sim_time_s, env.swarm.xy.tolist(), [float(env.xy[0]), float(env.xy[1]), env.heading],
                     result.collided))
        if result.collided:
            break
    return rows


@pytest.mark.parametrize("kind, seed", sorted(TODAY))
def test_labbots_and_robot_move_as_they_did_before_the_cost_cuts(make_env, kind, seed):
    rows = run_plan(make_env(kind, think_time_s=5), seed)
    assert len(rows) == len(TODAY[(kind, seed)])
    for (time_s, labbots, robot, collided), (time_then, labbots_then, robot_then, collided_then) in zip(
            rows, TODAY[(kind, seed)]):
        assert time_s == pytest.approx(time_then, abs=1e-6)
        assert np.abs(np.array(labbots) - np.array(labbots_then)).max() < 1.0  # mm
        assert np.abs(np.array(robot[:2]) - np.array(robot_then[:2])).max() < 1.0
        assert robot[2] == pytest.approx(robot_then[2], abs=1e-3)
        assert collided == collided_then


@pytest.mark.parametrize("kind, seed", [("MO", 5), ("DO", 11), ("DO", 4)])
def test_the_shortcuts_change_no_position_to_the_last_bit(make_env, request, kind, seed):
    fast = run_plan(make_env(kind, think_time_s=5), seed)
    request.getfixturevalue("reference_room")  # from here on: every check asked of Bullet
    slow = run_plan(make_env(kind, think_time_s=5), seed)
    assert fast == slow


def test_a_normal_draw_is_zero_plus_scale_times_a_standard_normal_bit_for_bit():
    """The tick draws ``0.0 + scale * standard_normal(n)`` for ``normal(0.0, scale, n)``: the same
    numbers (scales of zero included) and the same stream consumed after them."""
    for scales in ([5.59, 5.59], [0.0, 3.0], [0.0, 0.0], [7.0], [1.0, 2.0, 0.0]):
        scale = np.array(scales)
        for tick in range(300):
            a, b = np.random.default_rng([987654321012, tick]), np.random.default_rng([987654321012, tick])
            drawn = a.normal(0.0, scale, size=len(scale))
            ours = 0.0 + scale * b.standard_normal(len(scale))
            assert np.array_equal(drawn.view(np.uint64), ours.view(np.uint64))
            assert np.array_equal(a.random(len(scale)), b.random(len(scale)))
