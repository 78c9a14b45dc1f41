"""guard-mcp's policy file: which upstream tool is what, how motions are judged, what else may actuate.

``safeembodai guard-mcp --policy POLICY.yaml`` reads it; without one, the shipped policy for ros-mcp
3.x (``ros_mcp_policy.yaml`` beside this module) applies. ``docs/guard_mcp.md`` lists the keys. The
file is outside bytes (``safeembodai_core/trust/inventory.py``): read by the bounded reader of files from
elsewhere and validated strictly (:func:`~safeembodai_core.ros.robot_file.parse_yaml_model`): an
unknown key, a bool or text where a number belongs, a topic or type ROS would not accept is a
:class:`PolicyError` naming the file, the line and the key.

* ``tools`` maps each upstream tool by name to the kind guard-mcp treats it as (:data:`ToolKind`,
  whose arguments are ros-mcp 3.x's); a tool the policy does not map is refused when called.
* ``velocity_topics`` are judged (``geometry_msgs`` ``Twist`` or ``TwistStamped`` only): every
  publish to one is a motion the guard judges on the robot's own scan.
* ``allow`` lists what else may actuate, forwarded unjudged: topics with their types, services,
  actions, parameters. Anything not listed is refused (default: deny).
* ``security_prefix``, ``mark_untrusted``, ``state_management``: what the agent is told
  (:mod:`.agent`): the paper's prefix p in the server's instructions, upstream results marked as
  untrusted data, R_{i-1} with every refusal; each on by default, each may be turned off (an arm
  of an ablation without it).
"""

from __future__ import annotations

from importlib import resources
from pathlib import Path
from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, StrictBool, StrictFloat, StrictInt, StringConstraints, \
    field_validator, model_validator

from ..errors import SafeEmbodAIError
from ..rosbridge.names import RosNameError, normalize_type
from ..ros.robot_file import TOPIC, parse_yaml_model, read_yaml_text

#: The policy shipped for ros-mcp 3.x.
DEFAULT_POLICY = "ros_mcp_policy.yaml"
VELOCITY_TYPES = ("geometry_msgs/msg/Twist", "geometry_msgs/msg/TwistStamped")

#: A security-prefix variant's name, as the prompt builder's templates are named (``prompts/security/``).
Variant = Annotated[str, StringConstraints(pattern=r"^[A-Za-z0-9_][A-Za-z0-9_.-]*$", max_length=64)]
ToolKind = Literal["read_only", "publish_once", "publish_for_durations", "call_service", "send_action_goal",
                   "cancel_action_goal", "set_parameter", "delete_parameter", "connect_to_robot", "ping_robots"]
Name = Annotated[str, StringConstraints(pattern=TOPIC, max_length=256)]
TypeName = Annotated[str, StringConstraints(max_length=256)]
Number = Annotated[StrictFloat, Field(allow_inf_nan=False)]


class PolicyError(SafeEmbodAIError, ValueError):
    """A policy file that cannot be read or is not valid; the message names the file, line and key."""


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


def _types(types: list[str]) -> list[str]:
    for name in types:
        try:
            normalize_type(name)
        except RosNameError as error:
            raise ValueError(str(error)) from None
    return types


class Failures(_Strict):
    """Refusals in a row (any actuating call refused) before ``then`` applies: ``stop_only`` answers only
    stops until guard-mcp is reset (SIGHUP) or restarted; ``continue`` lets the agent go on."""

    threshold: Annotated[StrictInt, Field(ge=1, le=1000)] = 3
    then: Literal["stop_only", "continue"] = "stop_only"


class Allow(_Strict):
    """What may actuate unjudged: publishes to ``topics`` (each with the types it takes), calls of
    ``services``, goals to ``actions`` (and their cancelling), ``parameters`` set or deleted (ros-mcp's
    ``/node:name`` spelling, matched exactly)."""

    topics: dict[Name, list[TypeName]] = Field(default_factory=dict)
    services: list[Name] = Field(default_factory=list)
    actions: list[Name] = Field(default_factory=list)
    parameters: list[Annotated[str, StringConstraints(min_length=1, max_length=256)]] = Field(default_factory=list)

    @field_validator("topics")
    @classmethod
    def _topic_types(cls, topics: dict[str, list[str]]) -> dict[str, list[str]]:
        for types in topics.values():
            _types(types)
        return topics


class Policy(_Strict):
    """A guard-mcp policy, validated (module docstring; ``docs/guard_mcp.md`` for each key)."""

    mode: Literal["refuse", "limit"] = "refuse"
    horizon_s: Annotated[Number, Field(ge=0.05, le=30)] = 1.0
    scan_timeout_s: Annotated[Number, Field(ge=0.01, le=30)] = 0.5
    margin_mm: Annotated[Number, Field(ge=0, le=2000)] = 50.0
    slice_s: Annotated[Number, Field(ge=0.05, le=1.0)] = 0.2
    stream_hz: Annotated[Number, Field(ge=2, le=100)] = 10.0
    max_motion_s: Annotated[Number, Field(gt=0, le=300)] = 30.0
    max_messages: Annotated[StrictInt, Field(ge=1, le=1000)] = 100
    odom_topic: Name | None = "/odom"
    velocity_topics: dict[Name, list[TypeName]] = Field(
        default_factory=lambda: {"/cmd_vel": list(VELOCITY_TYPES)}, min_length=1)
    failures: Failures = Failures()
    allow: Allow = Allow()
    security_prefix: StrictBool | Variant = True
    mark_untrusted: StrictBool = True
    state_management: StrictBool = True
    tools: dict[Annotated[str, StringConstraints(min_length=1, max_length=128)], ToolKind] = Field(
        default_factory=dict)

    @field_validator("velocity_topics")
    @classmethod
    def _judged_types(cls, topics: dict[str, list[str]]) -> dict[str, list[str]]:
        for topic, types in topics.items():
            if not types:
                raise ValueError(f"{topic}: list the types it takes ({', '.join(VELOCITY_TYPES)})")
            for name in _types(types):
                if normalize_type(name) not in VELOCITY_TYPES:
                    raise ValueError(f"{topic}: {name} cannot be judged; a velocity topic takes "
                                     f"{' or '.join(VELOCITY_TYPES)} (ROS 1 spelling too)")
        return topics

    @model_validator(mode="after")
    def _disjoint(self) -> Policy:
        both = sorted(set(self.velocity_topics) & set(self.allow.topics))
        if both:
            raise ValueError(f"{', '.join(both)}: a topic is either judged (velocity_topics) or allowed unjudged "
                             "(allow.topics), not both")
        return self

    @property
    def prefix_variant(self) -> str | None:
        """The security-prefix variant the instructions carry (``true``: the paper's), None when off."""
        if self.security_prefix is False:
            return None
        return "paper" if self.security_prefix is True else str(self.security_prefix)

    def velocity_type(self, topic: str, msg_type: str) -> str | None:
        """The policy's spelling of ``msg_type`` (either ROS spelling) if velocity topic ``topic`` takes it."""
        return _spelled(self.velocity_topics.get(topic, []), msg_type)

    def allowed_type(self, topic: str, msg_type: str) -> str | None:
        """The policy's spelling of ``msg_type`` if allowed topic ``topic`` takes it."""
        return _spelled(self.allow.topics.get(topic, []), msg_type)


def _spelled(types: list[str], msg_type: str) -> str | None:
    try:
        wanted = normalize_type(msg_type)
    except RosNameError:
        return None
    return next((name for name in types if normalize_type(name) == wanted), None)


def parse_policy(text: str, source: str = "<policy>") -> Policy:
    """Validate policy ``text``; every problem at once, each naming ``source``, the line and the key."""
    return parse_yaml_model(text, source, Policy, PolicyError, "guard-mcp policy",
                            "a topic, service or action must be a full ROS name, such as /cmd_vel")


def read_policy(path: str | Path | None = None) -> Policy:
    """Read and validate the policy at ``path``; None: the shipped policy for ros-mcp 3.x."""
    if path is None:
        path = Path(str(resources.files(__package__).joinpath(DEFAULT_POLICY)))
    return parse_policy(read_yaml_text(path, PolicyError, "policy file"), str(path))
