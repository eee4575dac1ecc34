"""Pulse trains as analytic phase functions (DESIGN.md).

A line's phase Phi(t) counts its edges: the number of edges in (t0, t1] is
floor(Phi(t1)) - floor(Phi(t0)), and the N-th edge after t is found by solving
Phi(t') = level. Gyro pulses are emitted only at the rebalance loop's sampling instants
(Chart IV-2: t_N - t_0 = N tau), so a gyro line's phase is read at the last sampling
instant before t. No pulse is ever simulated one by one.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Protocol

import numpy as np

MEMO = 32  # phases a line keeps (a gate asks the same few instants several times)


class Revised(Protocol):
    """What a line's phases depend on: its ``revision`` counts the changes of their future."""

    revision: int


class PulseLine:
    """One pulse output of the world, named as on the patch panel (Chart II-2)."""

    def __init__(
        self,
        name: str,
        phase: Callable[[float], float],
        sample: tuple[float, float] | None = None,
        bipolar_sign: int = 0,
        phases: Callable[[np.ndarray], np.ndarray] | None = None,
        world: Revised | None = None,
    ) -> None:
        self.name = name
        self._phase = phase
        # ``world``: the phases asked at each instant are kept while its revision stands (a
        # counter's gate asks its ends for the level, the direction and the edge search:
        # half of a day's 33,500 asks repeat one of the last few); None: nothing is kept
        self._world = world
        self._memo: dict[float, float] = {}
        self._memo_revision = -1
        # the phase at many times in one evaluation, with the bits of ``phase`` at each
        self._phases = phases
        self.sample = sample  # (tau, offset) of a sampled output, or None
        self.bipolar_sign = bipolar_sign  # +1 / -1 for a gyro's + / - line, 0 otherwise
        self.net: PulseLine | None = None  # for + / - lines: the gyro's net train

    def phase(self, t: float) -> float:
        world = self._world
        if world is None:
            return self._phase(t)
        memo = self._memo
        if self._memo_revision != world.revision or len(memo) >= MEMO:
            memo.clear()
            self._memo_revision = world.revision
        v = memo.get(t)
        if v is None:
            v = memo[t] = self._phase(t)
        return v

    def last_sample(self, t: float) -> float:
        if self.sample is None:
            return t
        tau, off = self.sample
        return off + math.floor((t - off) / tau) * tau

    def next_sample(self, t: float) -> float:
        if self.sample is None:
            return t
        tau, off = self.sample
        return off + math.ceil((t - off) / tau - 1e-9) * tau

    def level(self, t: float) -> int:
        """floor(Phi) as seen at time t (edges at or before t)."""
        return math.floor(self.phase(self.last_sample(t)))

    def levels(self, t: np.ndarray) -> np.ndarray:
        """:meth:`level` at each of the times t, in one evaluation where the line has one."""
        t = np.asarray(t, dtype=float)
        if self.sample is not None:
            tau, off = self.sample
            t = off + np.floor((t - off) / tau) * tau
        if self._phases is None:
            ph = np.array([self._phase(float(x)) for x in t])
        else:
            ph = self._phases(t)
        return np.floor(ph).astype(np.int64)

    def count(self, t0: float, t1: float) -> int:
        """Edges in (t0, t1]; signed for a net train."""
        if self.net is not None:
            n = self.net.count(t0, t1)
            return max(self.bipolar_sign * n, 0)
        return self.level(t1) - self.level(t0)

    def direction(self, t: float) -> int:
        """+1 if the phase is increasing at t, -1 if decreasing (probed over 1 s)."""
        src = self.net if self.net is not None else self
        d = src.phase(t + 1.0) - src.phase(t)
        return 1 if d >= 0 else -1

    def estimate_edge(self, t: float, n: int) -> float | None:
        """A cheap guess of edge_after(t, n) from the local rate (None if not moving).

        Lets a counter sleep through most of a long gate without integrating the physics
        up to its end until it is nearly there (and not at all if it is stopped first).
        """
        src = self.net if self.net is not None else self
        p0 = src.phase(t)
        for dt in (1e-2, 1.0, 100.0):
            rate = abs(src.phase(t + dt) - p0) / dt
            if rate * dt >= 10.0:
                return t + n / rate
        return None

    def edge_after(self, t: float, n: int) -> float | None:
        """Time of the n-th edge after t (n >= 1) in the line's direction of motion.

        None if the line does not get there within :data:`HORIZON` (a stopped table).
        """
        src = self.net if self.net is not None else self
        d = src.direction(t) if self.net is None else self.bipolar_sign
        lev = src.level(t)
        target = lev + n if d > 0 else lev - n + 1
        tc = solve_crossing(src.phase, float(target), t, d)
        return None if tc is None else src.next_sample(tc)


HORIZON = 86400.0  # s; how far ahead an edge is looked for
XTOL, RTOL = 1e-12, 1e-15  # s, relative: the edge time's bracket at the end


def refine_bracket(phase: Callable[[float], float], c: float, d: int, a: float, fa: float,
                   b: float, fb: float) -> float:
    """Shrink a bracket (d fa < 0 <= d fb, fx = phase(x) - c) to XTOL + RTOL |b| by false
    position with the Illinois halving, and return its far end b, where the crossing has
    happened. Phases are nearly linear, so this takes a step or two (scipy's brentq did the
    same job; its import cost 0.3 s of every day's start)."""
    side = 0
    for _ in range(200):
        width = b - a
        tol = XTOL + RTOL * abs(b)
        if width <= tol:
            break
        t = b - fb * width / (fb - fa)
        t = min(max(t, a + 0.25 * tol), b - 0.25 * tol)  # strictly inside: always progress
        ft = phase(t) - c
        if d * ft >= 0:
            b, fb = t, ft
            if side > 0:
                fa *= 0.5
            side = 1
        else:
            a, fa = t, ft
            if side < 0:
                fb *= 0.5
            side = -1
    return b


def solve_crossing(phase: Callable[[float], float], c: float, t0: float, d: int) -> float | None:
    """First t > t0 with phase(t) = c, for a phase moving in direction d towards c."""
    f0 = phase(t0) - c
    if d * f0 >= 0:  # already there
        return t0
    step = 1e-3
    a, fa = t0, f0
    while True:
        b = a + step
        if b - t0 > HORIZON:
            return None
        fb = phase(b) - c
        if d * fb >= 0:
            break
        rate = (fb - fa) / step
        a, fa = b, fb
        # jump just past the predicted crossing; never shrink the step by more than half
        guess = -fa / rate * 1.001 + 1e-3 if d * rate > 0 else step * 4
        step = max(min(guess, HORIZON / 8), step * 0.5, 1e-6)
    # A few secant steps shrink the bracket cheaply (phases are nearly linear in time).
    for _ in range(4):
        if b - a < 1e-9:
            break
        ts = a - fa * (b - a) / (fb - fa)
        lo, hi = ts - 1e-6 * (b - a), ts + 1e-6 * (b - a)
        flo, fhi = phase(lo) - c, phase(hi) - c
        if d * flo < 0 <= d * fhi and a < lo and hi < b:
            a, fa, b, fb = lo, flo, hi, fhi
        else:
            break
    t = refine_bracket(phase, c, d, a, fa, b, fb)
    # The edge belongs to the instant the floor of the phase has changed: never return a
    # time a rounding error short of it, or the count at that time would miss the edge
    # (rising: phase >= c; falling: phase < c, strictly).
    step = max(abs(t) * 4e-16, 1e-13)
    while not (phase(t) >= c if d > 0 else phase(t) < c):
        t += step
        step *= 2
    return t
