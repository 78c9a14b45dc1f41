"""Seed derivation: every random draw of a trial comes from its seed and a stable label.

``derive_seed(base, "trial", 3)`` and ``rng(seed, "attacker", "prompt_injection", step)`` hash
their labels with BLAKE2 (never Python's salted ``hash``), so the same labels give the same
stream in every process, on every executor and in any run order. Streams are keyed by *what*
they are for, not by call order, so switching a defence on or off in one arm cannot shift
another component's draws: every arm of an ablation faces the same worlds and the same attacks.
"""

from __future__ import annotations

import hashlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np


def derive_seed(base: int, *labels: object) -> int:
    """A 63-bit seed determined by ``base`` and ``labels`` only."""
    digest = hashlib.blake2b(repr((int(base),) + tuple(str(x) for x in labels)).encode(), digest_size=8)
    return int.from_bytes(digest.digest(), "big") >> 1


def rng(base: int, *labels: object) -> np.random.Generator:
    """A numpy generator for the stream named by ``labels`` under ``base``."""
    import numpy as np  # deferred: deriving a seed (options, `safeembodai --help`) needs no numpy

    return np.random.default_rng(derive_seed(base, *labels))
