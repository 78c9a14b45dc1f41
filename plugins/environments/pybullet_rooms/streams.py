"""The Labbots' per-tick random streams, ``np.random.default_rng([seed, tick])``, made cheaply.

Each Labbot tick draws from a generator seeded by (the swarm's seed, the tick) alone
(:mod:`.labbots`). Building one with ``default_rng`` costs about 14 µs (a ``SeedSequence``, then a
``PCG64``), more than the rest of a tick's random draws; a trial's think times take thousands of
ticks. :class:`TickStreams` gives the very same generator state for far less: numpy's
``SeedSequence`` mixing (its algorithm is fixed by numpy's stream-compatibility policy, NEP 19)
is computed for a block of :data:`BLOCK` ticks at once over numpy ``uint32`` arrays, then the
``PCG64`` seeding (two steps of its 128-bit LCG) with Python integers, and the state is set on
one reused ``PCG64``. Each :class:`TickStreams` checks itself against ``default_rng`` for its first
ticks when built; should it ever differ (another numpy), it logs a warning and uses ``default_rng``.
"""

from __future__ import annotations

import numpy as np

from safeembodai_core.logs import get_logger

log = get_logger(__name__)

#: Ticks whose seed states are computed together.
BLOCK = 256
_MASK32 = 0xFFFFFFFF
_MASK128 = (1 << 128) - 1
# numpy/random/bit_generator.pyx: SeedSequence's constants (pool of 4 words)
_POOL = 4
_INIT_A, _MULT_A = 0x43B0D7E5, 0x931E8875
_INIT_B, _MULT_B = 0x8B51F9DD, 0x58F38DED
_MIX_MULT_L, _MIX_MULT_R = 0xCA01F9DD, 0x4973F715
_XSHIFT = 16
# numpy/random/src/pcg64: the 128-bit LCG's multiplier
_PCG_MULT = (2549297995355413924 << 64) + 4865540595714422341


def _words(value: int) -> list[int]:
    """``value`` as numpy's SeedSequence reads an int: its 32-bit words, least significant first."""
    if value < 0:
        raise ValueError("a seed must be non-negative")
    words = [value & _MASK32]
    value >>= 32
    while value:
        words.append(value & _MASK32)
        value >>= 32
    return words


class _Hash:
    """SeedSequence's hashmix: the running constant is the same for every tick of a block."""

    def __init__(self) -> None:
        self.const = _INIT_A

    def __call__(self, value):
        value = value ^ np.uint32(self.const)
        self.const = (self.const * _MULT_A) & _MASK32
        value = value * np.uint32(self.const)
        return value ^ (value >> np.uint32(_XSHIFT))


def _mix(x, y):
    result = np.uint32(_MIX_MULT_L) * x - np.uint32(_MIX_MULT_R) * y
    return result ^ (result >> np.uint32(_XSHIFT))


def _pool(entropy: list) -> list:
    """SeedSequence.mix_entropy over words that are numpy ``uint32`` arrays (one value per tick)."""
    hashmix = _Hash()
    zero = np.zeros_like(entropy[-1])
    mixer = [hashmix(entropy[i] if i < len(entropy) else zero) for i in range(_POOL)]
    for source in range(_POOL):
        for target in range(_POOL):
            if source != target:
                mixer[target] = _mix(mixer[target], hashmix(mixer[source]))
    for source in range(_POOL, len(entropy)):
        for target in range(_POOL):
            mixer[target] = _mix(mixer[target], hashmix(entropy[source]))
    return mixer


def _states(seed_words: list[int], ticks: np.ndarray) -> list[tuple[int, int]]:
    """Per tick: the ``PCG64`` (state, inc) that ``default_rng([seed, tick])`` starts from."""
    with np.errstate(over="ignore"):
        entropy = [np.full(len(ticks), word, dtype=np.uint32) for word in seed_words]
        entropy.append(ticks.astype(np.uint32))  # every tick is below 2**32: one word
        pool = _pool(entropy)
        const, words = _INIT_B, []
        for index in range(2 * 4):  # generate_state(4, uint64): eight 32-bit words
            value = pool[index % _POOL] ^ np.uint32(const)
            const = (const * _MULT_B) & _MASK32
            value = value * np.uint32(const)
            words.append((value ^ (value >> np.uint32(_XSHIFT))).tolist())
    states = []
    for w in zip(*words):
        seed0, seed1, inc0, inc1 = (w[0] | w[1] << 32, w[2] | w[3] << 32, w[4] | w[5] << 32, w[6] | w[7] << 32)
        inc = (((inc0 << 64) | inc1) << 1 | 1) & _MASK128
        state = inc  # pcg_setseq_128_srandom_r: state 0, one step, add the initial state, one step
        state = (state + ((seed0 << 64) | seed1)) & _MASK128
        state = (state * _PCG_MULT + inc) & _MASK128
        states.append((state, inc))
    return states


class TickStreams:
    """``generator(tick)``: a generator in the state ``np.random.default_rng([seed, tick])`` starts
    in. The one generator is reused: what it returned before is spent by the next call."""

    def __init__(self, seed: int) -> None:
        self.seed = int(seed)
        self._seed_words = _words(self.seed)
        self._bits = np.random.PCG64()
        self._generator = np.random.Generator(self._bits)
        self._blocks: dict[int, list[tuple[int, int]]] = {}
        self._exact = self._agrees()

    def generator(self, tick: int) -> np.random.Generator:
        if not self._exact or not 0 <= tick <= _MASK32:
            return np.random.default_rng([self.seed, tick])
        block, offset = divmod(tick, BLOCK)
        states = self._blocks.get(block)
        if states is None:
            if len(self._blocks) >= 8:  # a trial walks forward: old blocks are not asked again
                self._blocks.clear()
            start = block * BLOCK
            states = self._blocks[block] = _states(self._seed_words, np.arange(start, start + BLOCK, dtype=np.int64))
        state, inc = states[offset]
        self._bits.state = {"bit_generator": "PCG64", "state": {"state": state, "inc": inc},
                            "has_uint32": 0, "uinteger": 0}
        return self._generator

    def _agrees(self) -> bool:
        """Do the streams made here start as numpy's own (first ticks of this seed, and one later)?"""
        self._exact = True
        for tick in (0, 1, BLOCK + 3):
            ours = self.generator(tick).random(4)
            theirs = np.random.default_rng([self.seed, tick]).random(4)
            if not np.array_equal(ours, theirs):
                log.warning("labbots.streams_differ", seed=self.seed, tick=tick,
                            detail="numpy's SeedSequence or PCG64 differ from this copy; using default_rng")
                return False
        return True
