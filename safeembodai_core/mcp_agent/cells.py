"""What a scenario's arms and conditions mean for an agent that drives a served room through MCP.

An **arm** is the way to the robot. ``safety_validation: true`` puts guard-mcp between the agent and
ros-mcp: every motion judged on the robot's own scan by guard-mcp's rules, ``command_limits`` and
``swept_body`` (its ``margin_mm`` is the policy's); the arm's ``security_prefix`` and
``state_management`` are guard-mcp's policy keys of the same names (the prefix in the server's
instructions, R_{i-1} with each refusal). Without it the agent talks to ros-mcp directly, which tells
it nothing of the kind: those keys are then refused. ``failure_threshold`` is the agent's retries of a
refused step (Algorithm 1's N); when they are spent the trial ends ``safe_abort``.

A **condition** is its attackers. An attacker acts on the step's human instruction, as in any trial,
unless its ``label`` is ``camera_text`` (or begins ``camera_text_``): then what it writes is what the
camera reads at that step (the served ``/camera/text``) and the instruction is left alone. Such an
attacker draws from the stream of its component's name, not its label, so trial k of a condition that
injects through the instruction and of one that injects through the camera meet the same payloads at
the same steps.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from ..errors import SafeEmbodAIError
from ..loop.defences import Defences
from ..plugin.refs import ComponentRef
from ..scenario import Scenario

Channel = Literal["instruction", "camera_text"]
#: guard-mcp's rules, and the options of each that the policy carries.
GUARD_RULES = {"command_limits": (), "swept_body": ("margin_mm",)}
CAMERA_TEXT_LABEL = "camera_text"


@dataclass(frozen=True)
class Route:
    """How an arm reaches the robot: ``through_guard``, and the policy keys guard-mcp is given."""

    through_guard: bool
    policy: dict[str, Any] = field(default_factory=dict)
    failure_threshold: int = 3


@dataclass(frozen=True)
class Injection:
    """One attacker of a condition: its key in the records, the stream it draws from and its channel."""

    ref: ComponentRef
    channel: Channel

    @property
    def stream_key(self) -> str:
        return self.ref.use if self.channel == "camera_text" else self.ref.key


def route(name: str, arm: Defences) -> Route:
    """The arm ``name`` as a :class:`Route` (module docstring); refused when it asks what no route gives."""
    def refuse(why: str) -> SafeEmbodAIError:
        return SafeEmbodAIError(f"arm {name!r}: {why}")

    if arm.fresh_scan or arm.told or arm.on_exhausted != "abort":
        raise refuse("fresh_scan, told and on_exhausted (other than abort) are the trial loop's: an MCP agent "
                     "has none of them")
    if not arm.safety_validation:
        if arm.security_prefix is not False or arm.state_management is not False:
            raise refuse("security_prefix and state_management are what guard-mcp tells the agent: set "
                         "safety_validation: true (through guard-mcp), or leave them out")
        return Route(False, failure_threshold=arm.failure_threshold)
    policy: dict[str, Any] = {}
    for ref in arm.validators:
        if ref.use not in GUARD_RULES:
            raise refuse(f"guard-mcp judges with {' and '.join(GUARD_RULES)} only, not {ref.use!r}")
        extra = sorted(set(ref.options) - set(GUARD_RULES[ref.use]))
        if extra:
            raise refuse(f"{ref.use}'s {', '.join(extra)} cannot be given to guard-mcp (its policy takes "
                         f"{', '.join(GUARD_RULES[ref.use]) or 'none of its options'})")
        policy.update(ref.options)
    if arm.state_management == "last_command":
        raise refuse("state_management: last_command is the trial loop's; guard-mcp's is true or false")
    policy.update(security_prefix=arm.security_prefix, state_management=bool(arm.state_management))
    return Route(True, policy, arm.failure_threshold)


def injections(condition: str, scenario: Scenario) -> list[Injection]:
    """The attackers of ``condition`` with their channels (module docstring)."""
    found = []
    for ref in scenario.conditions[condition].attackers:
        label = ref.label or ""
        channel: Channel = ("camera_text" if label == CAMERA_TEXT_LABEL or label.startswith(CAMERA_TEXT_LABEL + "_")
                            else "instruction")
        found.append(Injection(ref, channel))
    keys = [injection.stream_key for injection in found if injection.channel == "camera_text"]
    if len(keys) != len(set(keys)):
        raise SafeEmbodAIError(f"condition {condition!r}: two camera_text attackers of one component would draw "
                               "the same payloads; use one")
    return found


class AttackNotSupported(SafeEmbodAIError):
    """An attacker acts on a channel an MCP agent's attacks cannot reach (the scan, R_{i-1})."""


def refuse_channel(key: str, channel: str) -> AttackNotSupported:
    return AttackNotSupported(f"attacker {key!r} acts on the {channel} channel: an MCP agent's attacks reach it "
                              "through the instruction or what the camera reads (docs/agent_ablation.md)")


def try_attackers(scenario: Scenario, plugins: Any, steps: int = 20) -> None:
    """Let every attacker act on ``steps`` steps of a stand-in trial; one that touches anything but the
    instruction is refused (:class:`AttackNotSupported`) before anything runs."""
    import numpy as np

    from ..contracts.attack_schedule import attack_stream
    from ..contracts.components import AttackSurface
    from ..models import LidarScan, Observation

    for condition in scenario.conditions:
        for found in injections(condition, scenario):
            attacker = plugins.registry.build_ref("attacker", found.ref, seed=scenario.seed)
            for step in range(1, steps + 1):
                surface = AttackSurface(step=step, instruction=scenario.instruction,
                                        observation=Observation(lidar=LidarScan(np.full(360, 1000.0), 6000.0)),
                                        reference_state=None, rng=attack_stream(scenario.seed, found.stream_key, step),
                                        limits=scenario.limits)
                for record in attacker.attack(surface):
                    if record.channel != "instruction":
                        raise refuse_channel(found.ref.key, record.channel)


def check(scenario: Scenario, plugins: Any = None) -> dict[str, Route]:
    """Every arm's route and every condition's attackers, checked before anything runs (the attackers tried
    on a stand-in trial when ``plugins`` are given)."""
    routes = {name: route(name, arm) for name, arm in scenario.arms.items()}
    for condition in scenario.conditions:
        injections(condition, scenario)
    if plugins is not None:
        try_attackers(scenario, plugins)
    return routes
