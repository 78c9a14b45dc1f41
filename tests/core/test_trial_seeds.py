"""Trial seeds: paired across arms and conditions of one environment, different across environments."""

from __future__ import annotations

from safeembodai_core.plugin.manager import load_plugins
from safeembodai_core.runs.runner import ScenarioRunner, trial_seed
from safeembodai_core.scenario import parse_scenario
from safeembodai_core.seeds import derive_seed

TWO_ROOMS = "name: x\ntrials: 3\nstate: memory\nenvironments: [{use: flatland, label: A}, {use: flatland, label: B}]\n"


def test_seed_comes_from_base_environment_and_index():
    scenario = parse_scenario(TWO_ROOMS + "seed: 5\n", "x.yaml")
    assert trial_seed(scenario, "A", 2) == derive_seed(5, "trial", "A", 2)
    assert trial_seed(scenario, "A", 2) != trial_seed(scenario, "B", 2) != trial_seed(scenario, "B", 1)


def test_every_arm_and_condition_of_a_room_pairs_up_and_rooms_differ():
    plugins = load_plugins(environ={})
    scenario = parse_scenario(TWO_ROOMS, "x.yaml", registry=plugins.registry)
    runner = ScenarioRunner(scenario, plugins)
    try:
        seeds: dict[tuple[str, int], set[int]] = {}
        for spec in runner.specs():
            seeds.setdefault((spec.environment, spec.index), set()).add(spec.seed)
        assert len(seeds) == 2 * 3 and all(len(s) == 1 for s in seeds.values())  # 2 arms x 2 conditions, one seed
        by_room = {room: [seeds[(room, k)].pop() for k in range(3)] for room in ("A", "B")}
        assert not set(by_room["A"]) & set(by_room["B"])
        # the same world kind, trial k: the robot starts elsewhere in each room
        first_a = runner.environment("A").reset(by_room["A"][0])
        first_b = runner.environment("B").reset(by_room["B"][0])
        assert (first_a.pose.x_mm, first_a.pose.y_mm) != (first_b.pose.x_mm, first_b.pose.y_mm)
    finally:
        runner.close()
