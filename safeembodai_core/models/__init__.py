"""The data contracts shared by the core loop and every plugin."""

from .control import DEFAULT_LIMITS, ControlLimits, ControlSignal, Straight, Turn
from .observation import GroundTruth, ImagePart, LidarScan, Modalities, Observation, Pose, TextPart
from .prompt import Prompt, PromptRequest
from .records import (
    Attempt,
    AttackRecord,
    ExecutedSignal,
    ExecutionResult,
    Outcome,
    ReferenceState,
    StepRecord,
    TokenUsage,
    TrialResult,
    TrialSpec,
    Verdict,
)
from .response import LLMResponse, PerceptionEntry, ResponseParseError, parse_response, response_json_schema

__all__ = [
    "DEFAULT_LIMITS", "Attempt", "AttackRecord", "ControlLimits", "ControlSignal", "ExecutedSignal",
    "ExecutionResult", "GroundTruth", "ImagePart", "LLMResponse", "LidarScan", "Modalities",
    "Observation", "Outcome", "PerceptionEntry", "Pose", "Prompt", "PromptRequest",
    "ReferenceState", "ResponseParseError", "StepRecord", "Straight", "TextPart", "TokenUsage",
    "TrialResult", "TrialSpec", "Turn", "Verdict", "parse_response",
    "response_json_schema",
]
