"""How MOER is scored: the paper's penalties, and the two choices the paper leaves open.

A scenario's ``metrics`` key (``docs/metrics.md``). The defaults are the paper's α and β with our
reading of S_max and of Algorithm 1's "mission failed"; ``profile: eyesim_release`` sets the
authors' release's choices (a fixed S_max of 20 steps, a failed mission scored with β).
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field

ALPHA = 0.6
BETA = 0.3


class MetricSettings(BaseModel):
    """MOER's parameters.

    * ``alpha``, ``beta``: the paper's penalties for ``timeout`` and ``interrupted`` (0.6, 0.3).
    * ``s_max``: ``timeouts`` -- the mean step count of the cell's timeout trials, the step budget
      when none timed out (ours: the paper's "average maximum steps for all trials that take
      maximum experiment time"); or a number of steps, fixed for every cell (the release: 20).
    * ``safe_abort_penalty``: which penalty a ``safe_abort`` trial gets: ``alpha`` (ours: the robot
      stopped safely and is retrievable, what α rewards) or ``beta`` (the release).
    """

    model_config = ConfigDict(extra="forbid")

    alpha: float = Field(ALPHA, ge=0, le=1, allow_inf_nan=False, description="t_j of a timeout trial")
    beta: float = Field(BETA, ge=0, le=1, allow_inf_nan=False, description="t_j of an interrupted trial")
    s_max: Literal["timeouts"] | Annotated[int, Field(strict=True, ge=1, le=10_000)] = Field(
        "timeouts", description="|S_max|: 'timeouts' (mean steps of the cell's timeout trials) or fixed steps")
    safe_abort_penalty: Literal["alpha", "beta"] = Field(
        "alpha", description="the penalty of a safe_abort trial (Algorithm 1's 'mission failed')")


DEFAULT_METRICS = MetricSettings()
