"""95% confidence intervals: Wilson for proportions, Newcombe's hybrid score interval for the difference of
two proportions, a seeded percentile bootstrap for means.

A mean of fewer than :data:`MIN_N_FOR_INTERVAL` values gets no interval: the bootstrap of one
value is a zero-width interval and of two values hardly more, either of which would read as
certainty. Such an estimate prints as ``0.53 (n=2)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

import numpy as np

Z95 = 1.959963984540054
BOOTSTRAP_RESAMPLES = 2000
MIN_N_FOR_INTERVAL = 3


@dataclass(frozen=True)
class Estimate:
    """A point value with its 95% interval; ``value`` is None when there is nothing to estimate."""

    value: float | None
    low: float | None = None
    high: float | None = None
    n: int = 0

    def fmt(self, digits: int = 2) -> str:
        """``0.53 [0.41, 0.66]``; ``0.53 (n=2)`` without an interval; ``n/a`` without a value."""
        if self.value is None:
            return "n/a"
        if self.low is None or self.high is None:
            return f"{self.value:.{digits}f}" + (f" (n={self.n})" if self.n else "")
        return f"{self.value:.{digits}f} [{self.low:.{digits}f}, {self.high:.{digits}f}]"


def wilson(successes: int, trials: int) -> Estimate:
    """Wilson score interval for a proportion (sensible at 0, 1 and small n)."""
    if trials <= 0:
        return Estimate(None, n=0)
    return Estimate(*_wilson_bounds(successes, trials), trials)


def _wilson_bounds(successes: int, trials: int) -> tuple[float, float, float]:
    """The proportion and its Wilson interval, ``(p, low, high)``, of ``trials > 0``."""
    p = successes / trials
    denominator = 1 + Z95**2 / trials
    centre = (p + Z95**2 / (2 * trials)) / denominator
    half = Z95 * math.sqrt(p * (1 - p) / trials + Z95**2 / (4 * trials**2)) / denominator
    # exact where the algebra is (low = 0 at 0 successes, high = 1 at all), not 5.6e-17 or 0.9999999999999999;
    # elsewhere within [0, 1] and around p whatever the round-off
    low = 0.0 if successes <= 0 else min(p, max(0.0, centre - half))
    high = 1.0 if successes >= trials else max(p, min(1.0, centre + half))
    return p, low, high


def newcombe(successes_a: int, trials_a: int, successes_b: int, trials_b: int) -> Estimate:
    """Difference of two independent proportions, p_a - p_b, with Newcombe's hybrid score 95% interval
    (Newcombe 1998, Statistics in Medicine 17:873-890, method 10), built from the two :func:`wilson` intervals:
    low = d - sqrt((p_a - low_a)^2 + (high_b - p_b)^2), high = d + sqrt((high_a - p_a)^2 + (p_b - low_b)^2).
    No value when either side has no trials; ``n`` is ``trials_a + trials_b``."""
    if trials_a <= 0 or trials_b <= 0:
        return Estimate(None, n=0)
    p_a, low_a, high_a = _wilson_bounds(successes_a, trials_a)
    p_b, low_b, high_b = _wilson_bounds(successes_b, trials_b)
    d = p_a - p_b
    low = d - math.sqrt((p_a - low_a) ** 2 + (high_b - p_b) ** 2)
    high = d + math.sqrt((high_a - p_a) ** 2 + (p_b - low_b) ** 2)
    return Estimate(d, max(-1.0, low), min(1.0, high), trials_a + trials_b)


def bootstrap_mean(values: Sequence[float], seed: int = 0) -> Estimate:
    """Mean with a percentile-bootstrap 95% interval (seeded: the same data give the same interval);
    no interval for fewer than :data:`MIN_N_FOR_INTERVAL` values."""
    data = np.asarray([v for v in values if v is not None], dtype=float)
    if data.size == 0:
        return Estimate(None, n=0)
    mean = float(data.mean())
    if data.size < MIN_N_FOR_INTERVAL:
        return Estimate(mean, n=int(data.size))
    rng = np.random.default_rng(seed)
    samples = rng.choice(data, size=(BOOTSTRAP_RESAMPLES, data.size), replace=True).mean(axis=1)
    low, high = np.percentile(samples, [2.5, 97.5])
    return Estimate(mean, float(low), float(high), int(data.size))
