"""Every arm of an ablation faces the same attacks at the same steps."""

from __future__ import annotations

from safeembodai_core.testing import answer, tiny_scenario, turn

ATTACKERS = [
    {"use": "prompt_injection", "options": {"rate": 0.4}},
    {"use": "lidar_spoof", "options": {"rate": 0.4, "centre_deg": None}},
    {"use": "state_poisoning", "options": {"rate": 0.5}},
]
ARMS = {
    "baseline": {},
    "safeembodai": {"security_prefix": True, "state_management": True, "safety_validation": True,
                    "validators": ["command_limits", "lidar_clearance", "footprint_sweep"]},
    "spotlight_only": {"security_prefix": "spotlight"},
}


def attacks_by_channel(steps, channel: str) -> list[tuple[int, str, str]]:
    return [(s.step, a.kind, a.payload) for s in steps for a in s.attacks if a.channel == channel]


def test_instruction_and_sensor_attacks_are_identical_across_arms(cell):
    scenario = tiny_scenario([answer(turn(25))], max_steps=12, arms=ARMS,
                             conditions={"attack": {"attackers": ATTACKERS}})
    runs = {arm: cell(scenario, arm, "attack")[1] for arm in ARMS}
    assert all(len(steps) == 12 for steps in runs.values())
    for channel in ("instruction", "sensor"):
        patterns = [attacks_by_channel(steps, channel) for steps in runs.values()]
        assert patterns[0] and all(p == patterns[0] for p in patterns), channel
    # state poisoning needs R_{i-1}: only the arm with state management is exposed to it
    assert attacks_by_channel(runs["safeembodai"], "state")
    assert not attacks_by_channel(runs["baseline"], "state") and not attacks_by_channel(runs["spotlight_only"], "state")


def test_an_attackers_stream_does_not_depend_on_the_other_attackers(cell):
    alone = tiny_scenario([answer(turn(25))], max_steps=10,
                          conditions={"attack": {"attackers": ATTACKERS[:1]}})
    together = tiny_scenario([answer(turn(25))], max_steps=10,
                             conditions={"attack": {"attackers": ATTACKERS}})
    first = attacks_by_channel(cell(alone, "arm", "attack")[1], "instruction")
    second = attacks_by_channel(cell(together, "arm", "attack")[1], "instruction")
    assert first and first == second


def test_a_labelled_second_copy_of_an_attacker_draws_its_own_stream(cell):
    twice = [{"use": "prompt_injection", "options": {"rate": 0.5}},
             {"use": "prompt_injection", "label": "second_injector", "options": {"rate": 0.5}}]
    scenario = tiny_scenario([answer(turn(25))], max_steps=12, conditions={"attack": {"attackers": twice}})
    steps = cell(scenario, "arm", "attack")[1]
    counts = [len(s.attacks) for s in steps]
    assert 2 in counts and 1 in counts  # the two copies do not always agree


def test_the_attacker_streams_are_drawn_in_one_place(repo):
    """The pairing rule (trial seed, attacker key, step: never the arm) is written once, in
    ``attacks.attack_stream``; the loop, ``fresh_scan`` and the Gymnasium env call it through
    ``run_attackers``. A second copy could drift and unpair the arms."""
    import re

    written = [path.relative_to(repo).as_posix()
               for folder in ("safeembodai_core", "plugins") for path in (repo / folder).rglob("*.py")
               if re.search(r"""^\s*[^#\s`].*\brng\([^)]*["']attacker["']""", path.read_text(encoding="utf-8"), re.M)
               and path.name != "seeds.py"]  # seeds.py's docstring shows the call as an example
    assert written == ["safeembodai_core/contracts/attack_schedule.py"]
    users = [path.relative_to(repo).as_posix() for path in (repo / "safeembodai_core").rglob("*.py")
             if "run_attackers(" in path.read_text(encoding="utf-8")]
    assert sorted(users) == ["safeembodai_core/contracts/attack_schedule.py",
                             "safeembodai_core/integrations/gym/env.py", "safeembodai_core/loop/fresh_scan.py",
                             "safeembodai_core/loop/trial.py"]
