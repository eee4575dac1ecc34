"""The IEU's samples counted in blocks: one vectorised evaluation of the phase functions
at the latch instants of many consecutive samples (issue 17).

A sample's counts are differences of line levels (floors of phases) at its two latch
instants. A block holds the next latch instants (solved one after another exactly as the
sampling loop solves them) and every line's level at each, from one call of the lines'
vectorised phases; each level has the bits the line's scalar phase gives, so the counts
are those of the direct evaluation. A block is used only while the world's revision is the
one it was computed under: a table command (``World.changed``) makes the next sample
compute a new block from its opening latch. Frames still leave one sample at a time.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from sim.isu.pulses import PulseLine
from sim.isu.world import World

BLOCK_S = 200.0  # simulated seconds of samples computed at once
MAX_SAMPLES = 256  # samples in a block, at most
FIRST_SAMPLES = 8  # a sampling's first block; each next one twice as long, up to the most


class SampleBlocks:
    """Latch instants and line levels of the coming samples of one sampling (one START)."""

    def __init__(self, world: World, lines: Sequence[PulseLine],
                 next_latch: Callable[[float], float], period_s: float) -> None:
        self.world = world
        self.lines = tuple(lines)
        self._next_latch = next_latch  # the latch after a latch instant
        self.size = max(1, min(MAX_SAMPLES, int(BLOCK_S / max(period_s, 1e-9))))
        # a short sampling (the line checks of Charts III-4 and III-8 take two samples)
        # computes a short block; a long one reaches ``size`` after a few (issue 17)
        self._next_size = min(self.size, FIRST_SAMPLES)
        self._after: dict[float, float] = {}  # latch instant -> the next one
        self._index: dict[float, int] = {}  # latch instant -> column of ``_levels``
        self._levels = np.zeros((len(self.lines), 0), dtype=np.int64)
        self._steps: list[list[int]] = []  # column i: the counts from latch i to latch i + 1
        self._revision = -1

    def next_latch(self, t: float) -> float:
        """The latch after latch instant ``t`` (held from the block, else solved)."""
        nxt = self._after.get(t)
        if nxt is None:
            nxt = self._next_latch(t)
            self._after[t] = nxt
        return nxt

    def counts(self, t0: float, t1: float) -> list[int]:
        """Each line's count over the sample (t0, t1]: level(t1) - level(t0)."""
        i0, i1 = self._index.get(t0), self._index.get(t1)
        if i0 is None or i1 is None or self._revision != self.world.revision:
            self._compute(t0)
            i0, i1 = self._index[t0], self._index.get(t1)
            if i1 is None:  # t1 is not the latch after t0: count these two instants alone
                lv = np.stack([ln.levels(np.array([t0, t1])) for ln in self.lines])
                return [int(x) for x in lv[:, 1] - lv[:, 0]]
        if i1 == i0 + 1:  # one sample: its counts are held as Python ints
            return list(self._steps[i0])
        d = self._levels[:, i1] - self._levels[:, i0]
        return [int(x) for x in d]

    def _compute(self, t0: float) -> None:
        """Latch instants from ``t0`` on and every line's level at each, the world as it is."""
        times = [t0]
        after: dict[float, float] = {}
        n, self._next_size = self._next_size, min(self.size, 2 * self._next_size)
        for _ in range(n):
            nxt = self._after.get(times[-1])
            if nxt is None:
                nxt = self._next_latch(times[-1])
            after[times[-1]] = nxt
            times.append(nxt)
        self._after = after
        t = np.array(times)
        self._levels = np.stack([ln.levels(t) for ln in self.lines])
        self._steps = np.diff(self._levels, axis=1).T.tolist()
        self._index = {x: i for i, x in enumerate(times)}
        self._revision = self.world.revision
