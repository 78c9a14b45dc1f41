"""TickStreams: the generator ``np.random.default_rng([seed, tick])`` starts as, made cheaply."""

from __future__ import annotations

import numpy as np
import pytest

from safeembodai_plugins.environments.pybullet_rooms import streams
from safeembodai_plugins.environments.pybullet_rooms.streams import BLOCK, TickStreams

SEEDS = [0, 1, 2**32 - 1, 2**32, 2**63 - 1, 2**64 + 5, 2**96 + 7] + [int(s) for s in
                                                                    np.random.default_rng(51).integers(0, 2**63, 6)]


@pytest.mark.parametrize("seed", SEEDS)
def test_each_tick_draws_what_default_rng_of_seed_and_tick_draws(seed):
    made = TickStreams(seed)
    for tick in list(range(2 * BLOCK + 5)) + [10**6, 2**32 - 1]:
        ours, theirs = made.generator(tick), np.random.default_rng([seed, tick])
        assert np.array_equal(ours.standard_normal(3), theirs.standard_normal(3))
        assert np.array_equal(ours.random(3), theirs.random(3))


def test_ticks_asked_out_of_order_and_again_draw_the_same():
    made = TickStreams(1234)
    first = [made.generator(tick).random() for tick in (700, 3, 700, 2000, 3, 0)]
    assert first == [np.random.default_rng([1234, tick]).random() for tick in (700, 3, 700, 2000, 3, 0)]


def test_a_copy_that_disagrees_with_numpy_falls_back_to_default_rng(monkeypatch):
    monkeypatch.setattr(streams, "_states", lambda words, ticks: [(12345, 67891)] * len(ticks))
    made = TickStreams(99)
    assert made._exact is False
    assert made.generator(5).random() == np.random.default_rng([99, 5]).random()
