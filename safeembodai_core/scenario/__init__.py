"""Scenarios: YAML files that compose plugins into an ablation (environments x arms x conditions)."""

from .loader import load_scenario, parse_scenario
from .model import Condition, Scenario

__all__ = ["Condition", "Scenario", "load_scenario", "parse_scenario"]
