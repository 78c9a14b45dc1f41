"""The guarded control loop of the paper (Algorithm 1 inside the per-trial step loop)."""

from .defences import Defences
from .guarded_step import decide
from .trial import LoopSettings, TrialParts, run_trial

__all__ = ["Defences", "LoopSettings", "TrialParts", "decide", "run_trial"]
