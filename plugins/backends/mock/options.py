"""The options of the ``mock`` backend (the package registers them)."""

from __future__ import annotations

from typing import Literal, TypedDict

from pydantic import Field

from safeembodai_core.contracts.descriptions import BackendDescription, BackendOptions


class _Bounds(TypedDict):
    """Keyword bounds spread into ``Field`` (typed, so each matches ``Field``'s parameter)."""

    ge: float
    le: float


_P: _Bounds = {"ge": 0.0, "le": 1.0}


#: The options that set ADR and how often an injection is obeyed: inputs behind numbers that look
#: like findings (the report names them with their values).
INPUTS = (
    ("flag_injection_p", "P(flags an injected instruction), arms without the security prefix: ADR's input"),
    ("flag_injection_p_secure", "the same with the security prefix: ADR's input"),
    ("false_flag_p", "P(flags an honest instruction): false alarms' input"),
    ("obey_injection_p", "P(obeys an injected instruction it did not flag), no security prefix"),
    ("obey_injection_p_secure", "the same with the security prefix"),
    ("obey_factor_with_reference", "multiplies the obey probability when R_{i-1} is in the prompt"),
)
#: The pilot's other weaknesses: they shape MOER, TLR, collisions and refusals.
WEAKNESSES = ("ignore_clearance_p", "lidar_misread_sd", "distance_error_sd", "angle_error_sd_deg",
              "miss_target_p", "bearing_mirror_p", "recall_target_p", "explore_forward_p", "malformed_p",
              "limit_violation_p", "feedback_compliance_p")


class MockOptions(BackendOptions):

    # prompt injection
    obey_injection_p: float = Field(0.85, **_P, description="follows a misaligned instruction (no security prefix)")
    obey_injection_p_secure: float = Field(0.35, **_P, description="... with the security prefix")
    obey_factor_with_reference: float = Field(0.8, **_P, description="multiplies the above when R_{i-1} is present")
    flag_injection_p: float = Field(0.2, **_P, description="sets is_attack on a misaligned instruction (no prefix)")
    flag_injection_p_secure: float = Field(0.55, **_P, description="... with the security prefix")
    false_flag_p: float = Field(0.0, **_P, description="flags a benign instruction as an attack")
    # numbers and output
    distance_error_sd: float = Field(0.2, ge=0.0, le=2.0, description="relative error of straight distances")
    angle_error_sd_deg: float = Field(4.0, ge=0.0, le=45.0, description="error of turn angles")
    ignore_clearance_p: float = Field(0.25, **_P, description="plans a straight without checking the LiDAR")
    lidar_misread_sd: float = Field(0.35, ge=0.0, le=2.0, description="relative error reading LiDAR distances")
    limit_violation_p: float = Field(0.02, **_P, description="writes a distance beyond the actuation limit")
    malformed_p: float = Field(0.02, **_P, description="first answer of a step is not schema-valid JSON")
    feedback_compliance_p: float = Field(0.9, **_P, description="on a retry, obeys a refusal's advice")
    retry: Literal["redraw", "amend"] = Field("redraw", description=(
        "on a retry: 'redraw' plans afresh and shortens every straight to the least safe distance given; "
        "'amend' resends the refused plan up to the refused straight, shortened, when each refusal named "
        "its signal and how far is safe (else redraws)"))
    # perception, memory and search
    miss_target_p: float = Field(0.3, **_P, description="overlooks the can when it is under 6% of image height")
    bearing_mirror_p: float = Field(0.25, **_P, description="confuses left and right when turning to the can")
    recall_target_p: float = Field(0.9, **_P, description="with R_{i-1}: turns back to a can seen last step")
    search_turn_deg: float = Field(60.0, gt=0.0, lt=180.0, description="typical search turn")
    wait_turn_deg: float = Field(5.0, gt=0.0, lt=180.0, description=(
        "turn in place when a refusal asks to wait for a mover to pass and no straight is left"))
    search_left_p: float = Field(0.5, **_P, description="searches to the left when nothing says which way")
    explore_forward_p: float = Field(0.3, **_P, description="searches by driving into open space instead of turning")
    approach_stop_mm: float = Field(300.0, ge=0.0, description="aims to stop this far from the can's surface")
    clearance_margin_mm: float = Field(200.0, ge=0.0, description="keeps this far from obstacles when it checks")
    max_straights_per_answer: int = Field(2, ge=1, le=50, description="straights it chains when the can is far")
    corridor_mm: float = Field(250.0, gt=0.0, description="half-width of the path it checks for obstacles")
    target_height_mm: float = Field(120.0, gt=0.0, description="height it assumes the can has (distance by size)")
    # reading the prompt, reporting usage
    camera_fov_deg: float = Field(60.0, gt=10, lt=170, description="camera field of view, for bearings")
    lidar_image_range_mm: float = Field(4000.0, gt=0, description="LiDAR picture range when it has no 1 m ring")
    token_counting: Literal["litellm", "estimate"] = Field("litellm", description="how usage is counted")
    token_model: str = Field("gpt-4o", min_length=1, description="model whose tokenizer counts usage")
    token_image_detail: Literal["low", "high", "auto"] = Field("low", description="image detail for counting")
    latency_s: float = Field(0.0, ge=0.0, description="latency to report (0: the real compute time)")

    def describe(self) -> BackendDescription:
        values = self.model_dump()
        return BackendDescription(
            model=f"none: simulated, tokens counted as for {self.token_model}",
            simulated="simulated pilot (mock): not a measurement of an LLM",
            why="Every number below comes from a simulated pilot whose weaknesses are configured; the numbers its "
                "configuration sets are listed under *Pilot's configured inputs*.",
            pilot="simulated pilot (mock), not an LLM",
            inputs=tuple((name, values[name], what) for name, what in INPUTS),
            weaknesses=tuple((name, values[name]) for name in WEAKNESSES))
