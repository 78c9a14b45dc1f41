"""Safety validation: the context a rule judges a plan in, and the plan's validation (``context``).

The names of the previous release's ``safeembodai_core.validation`` module are kept here; the rules
themselves are validator plugins (``plugins/validators``).
"""

from .context import PastScan, SectorReading, ValidationContext, Validator, validate_plan

__all__ = ["PastScan", "SectorReading", "ValidationContext", "Validator", "validate_plan"]
