"""The data contracts shared by the core loop and every plugin."""

from .control import DEFAULT_LIMITS, ControlLimits, ControlSignal, Straight, Turn
from .observation import GroundTruth, ImagePart, LidarScan, Modalities, Observation, Pose, TextPart
from .prompt import Prompt, PromptRequest
from .records import (
    Advice,
    Attempt,
    AttackRecord,
    Enforced,
    ExecutedSignal,
    ExecutionResult,
    Outcome,
    ReferenceState,
    Refusal,
    StepRecord,
    TokenUsage,
    TrialResult,
    TrialSpec,
    Verdict,
)
from .response import LLMResponse, PerceptionEntry, ResponseParseError, response_json_schema
from .reply import BackendReply, parse_response, read_reply

__all__ = [
    "DEFAULT_LIMITS", "Advice", "Attempt", "Enforced", "BackendReply", "AttackRecord", "ControlLimits", "ControlSignal",
    "ExecutedSignal",
    "ExecutionResult", "GroundTruth", "ImagePart", "LLMResponse", "LidarScan", "Modalities",
    "Observation", "Outcome", "PerceptionEntry", "Pose", "Prompt", "PromptRequest",
    "ReferenceState", "Refusal", "ResponseParseError", "StepRecord", "Straight", "TextPart", "TokenUsage",
    "TrialResult", "TrialSpec", "Turn", "Verdict", "parse_response", "read_reply",
    "response_json_schema",
]
