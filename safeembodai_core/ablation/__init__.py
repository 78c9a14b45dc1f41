"""The ablation engine: every trial of every cell, in parallel, resumable, then metrics and reports."""

from .engine import Ablation, AblationError
from ..runs.folder import RunFolder

__all__ = ["Ablation", "AblationError", "RunFolder"]
