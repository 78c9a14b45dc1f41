"""A scenario's arms as the way to the robot (ros-mcp direct, or through guard-mcp with its policy keys) and its
conditions' attackers as the channel they inject through (the instruction, or what the camera reads)."""

from __future__ import annotations

import pytest

from safeembodai_core.scenario.reading import checked_scenario
from safeembodai_core.errors import SafeEmbodAIError
from safeembodai_core.loop.defences import Defences
from safeembodai_core.mcp_agent.cells import AttackNotSupported, check, injections, route
from safeembodai_core.scenario import Scenario

GUARD = {"safety_validation": True, "validators": ["command_limits", {"use": "swept_body",
                                                                     "options": {"margin_mm": 80}}]}


def test_the_shipped_scenario_has_a_direct_arm_and_one_through_guard_mcp(repo, built_plugins):
    scenario, plugins = checked_scenario(repo / "scenarios/mcp.yaml", built_plugins)
    routes = check(scenario, plugins)
    assert not routes["ros_mcp_direct"].through_guard and routes["guard_mcp"].through_guard
    assert routes["guard_mcp"].policy == {"margin_mm": 50, "security_prefix": True, "state_management": True}
    assert [i.channel for i in injections("attack_tool_result", scenario)] == ["camera_text"]
    assert [i.channel for i in injections("attack_instruction", scenario)] == ["instruction"]
    assert injections("attack_tool_result", scenario)[0].stream_key == "prompt_injection"  # paired with the other


def test_an_arm_through_guard_mcp_gives_it_the_rules_options_and_the_defences_it_carries():
    through = route("g", Defences.model_validate({**GUARD, "security_prefix": "hierarchy", "failure_threshold": 1}))
    assert through.policy == {"margin_mm": 80, "security_prefix": "hierarchy", "state_management": False}
    assert through.failure_threshold == 1


@pytest.mark.parametrize("arm, why", [
    ({"security_prefix": True}, "what guard-mcp tells the agent"),
    ({"state_management": True}, "what guard-mcp tells the agent"),
    ({"safety_validation": True}, "not 'lidar_clearance'"),  # the trial loop's default rules
    ({**GUARD, "validators": [{"use": "swept_body", "options": {"sweep_steps": 4}}]}, "sweep_steps"),
    ({**GUARD, "fresh_scan": True}, "fresh_scan"),
    ({**GUARD, "on_exhausted": "enforce"}, "on_exhausted"),
    ({**GUARD, "state_management": "last_command"}, "last_command"),
])
def test_an_arm_that_asks_what_no_route_gives_is_refused_by_name(arm, why):
    with pytest.raises(SafeEmbodAIError, match=why):
        route("a", Defences.model_validate(arm))


def test_two_camera_text_attackers_of_one_component_are_refused():
    scenario = Scenario(name="t", environments=["SO"], conditions={"c": {"attackers": [
        {"use": "prompt_injection", "label": "camera_text"}, {"use": "prompt_injection", "label": "camera_text_2"}]}})
    with pytest.raises(SafeEmbodAIError, match="two camera_text attackers"):
        injections("c", scenario)


@pytest.mark.parametrize("attacker", ["lidar_spoof", {"use": "lidar_spoof", "label": "camera_text"}])
def test_an_attacker_of_the_scan_is_refused_before_anything_runs(built_plugins, attacker):
    scenario = Scenario(name="t", environments=["SO"], conditions={"c": {"attackers": [attacker]}},
                        arms={"direct": {}})
    with pytest.raises(AttackNotSupported, match="sensor channel"):
        check(scenario, built_plugins)
