"""Which defences an arm switches on: the three of the paper, each independent."""

from __future__ import annotations

from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, SerializerFunctionWrapHandler, field_validator, model_serializer

from ..plugin.refs import ComponentRef, unique_keys

DEFAULT_RULES = ("command_limits", "lidar_clearance")


class Defences(BaseModel):
    """One arm of an ablation.

    * ``security_prefix``: secure prompting; ``false`` for Y = {B}, ``true`` for the paper's
      prefix p, or the name of a prefix variant shipped by the prompt builder.
    * ``state_management``: put the reference state R_{i-1} into the prompt of step i: ``true``
      (the paper's R_{i-1}: signals with their results, and what the LLM perceived and planned), or
      ``last_command`` (the authors' release: only "Last Command:" with the previous step's signals,
      "None" at step 1; eyesimLLM ``src/llm/prompt.py:12``, ``src/discrete_robot/__init__.py:66-70``).
    * ``safety_validation``: check every control signal with ``validators`` before execution.
    * ``failure_threshold``: N of Algorithm 1, the retries allowed after a refused answer. Answers
      that do not parse are refused and retried in every arm: the robot cannot execute them.
    * ``on_exhausted``: when N retries are spent, ``abort`` ends the trial (``safe_abort``, the
      paper's "mission failed"); ``hold`` skips the step without moving and carries on; ``enforce``
      (ours, not the paper's) runs the rules' own cut of the last parsed, refused answer -- what its
      refusals' advice allows, judged again by every rule -- and holds when nothing of it is safe
      (:mod:`safeembodai_core.loop.enforce`); with ``failure_threshold: 0``: cut at the first refusal.
    * ``fresh_scan``: the validators judge a LiDAR scan read when the LLM's answer arrives (the
      environment's :meth:`~safeembodai_core.contracts.components.Environment.sense`, after the think
      time), not the scan the step's prompt was built from; the step's scan joins
      ``ValidationContext.history``. Ours, not the paper's: V(C) reads l_i, the step's scan.
    * ``told``: the arm's rules are told what only the simulator knows about its world (options
      declared world-private, :mod:`safeembodai_core.trust.world_private`, e.g. the Labbots' cruising
      speed): an oracle kept for comparison. ``report.md`` says so under the arms table. Recorded
      only when true, so that the fingerprints of scenarios written before it stay as they were.
    """

    model_config = ConfigDict(extra="forbid")

    security_prefix: bool | str = False
    state_management: bool | Literal["last_command"] = False
    safety_validation: bool = False
    validators: list[ComponentRef] = Field(default_factory=lambda: [ComponentRef(use=n) for n in DEFAULT_RULES])
    failure_threshold: int = Field(3, ge=0, le=20)
    on_exhausted: Literal["abort", "hold", "enforce"] = "abort"
    fresh_scan: bool = False
    told: bool = False

    @model_serializer(mode="wrap")
    def _told_only_when_true(self, handler: SerializerFunctionWrapHandler) -> dict[str, Any]:
        data = handler(self)
        if isinstance(data, dict) and not self.told:
            data.pop("told", None)
        return data

    @field_validator("validators")
    @classmethod
    def _unique(cls, refs: list[ComponentRef]) -> list[ComponentRef]:
        return unique_keys(refs, "validator")

    @property
    def prefix_variant(self) -> str | None:
        if self.security_prefix is False:
            return None
        return "paper" if self.security_prefix is True else str(self.security_prefix)


BASELINE = Defences()
SAFEEMBODAI = Defences(security_prefix=True, state_management=True, safety_validation=True)
