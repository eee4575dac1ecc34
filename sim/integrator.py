"""Running integrals of the ISU's input rates, exact to quadrature precision and O(1) per query.

Time is cut into fixed cells of ``h`` seconds; the integral over each cell is computed once
(Gauss-Legendre, split at table segment starts and subdivided when the table turns fast)
and summed into a cumulative table. A query at t costs one partial cell. Because cells are
fixed, the result does not depend on the order of queries. A world change at tc (a table
command) drops the cells after tc; they are recomputed with the new plan when needed.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

GL_X, GL_W = np.polynomial.legendre.leggauss(8)
MAX_SWEEP = math.pi / 2  # rad of table travel per quadrature piece


class CellIntegral:
    def __init__(
        self,
        m: int,
        h: float,
        integrand: Callable[[np.ndarray], np.ndarray],
        increments: Callable[[np.ndarray, np.ndarray], np.ndarray],
        breakpoints: Callable[[float, float], list[float]],
        max_rate: Callable[[float, float], float],
        abs_rate: Callable[[np.ndarray], np.ndarray],
    ) -> None:
        self.m = m
        self.h = h
        self._integrand = integrand
        self._increments = increments
        self._breakpoints = breakpoints
        self._max_rate = max_rate
        self._abs_rate = abs_rate
        self.cum = np.zeros((1, m))

    def _pieces(self, t0: float, t1: float) -> list[tuple[float, float]]:
        edges = [t0, *self._breakpoints(t0, t1), t1]
        out = []
        for a, b in zip(edges[:-1], edges[1:], strict=True):
            if b <= a:
                continue
            n = max(1, math.ceil(self._max_rate(a, b) * (b - a) / MAX_SWEEP))
            xs = np.linspace(a, b, n + 1)
            out.extend(zip(xs[:-1], xs[1:], strict=True))
        return out

    def _integrate(self, groups: list[list[tuple[float, float]]]) -> np.ndarray:
        """Integral over each group of pieces, shape (len(groups), m)."""
        flat = [p for g in groups for p in g]
        if not flat:
            return np.zeros((len(groups), self.m))
        ab = np.array(flat)
        a, b = ab[:, 0], ab[:, 1]
        half = 0.5 * (b - a)
        mid = 0.5 * (a + b)
        nodes = (mid[:, None] + half[:, None] * GL_X[None, :]).ravel()
        vals = self._integrand(nodes).reshape(len(flat), GL_X.size, self.m)
        piece = np.einsum("pkm,k->pm", vals, GL_W) * half[:, None]
        piece = piece + self._increments(a, b)
        starts = np.cumsum([0] + [len(g) for g in groups[:-1]])
        sums = np.zeros((len(groups), self.m))
        nonempty = np.array([len(g) > 0 for g in groups])
        if nonempty.any():
            sums[nonempty] = np.add.reduceat(piece, starts[nonempty], axis=0)
        return sums

    def _ensure(self, k: int) -> None:
        have = self.cum.shape[0] - 1  # cells integrated
        if k <= have:
            return
        t0, t1 = have * self.h, k * self.h
        bps = self._breakpoints(t0, t1)
        busy = {int(b // self.h) for b in bps}
        # Cells without a segment start inside: one rate probe decides the subdivision.
        edges = np.arange(have, k + 1) * self.h
        r = self._abs_rate(edges)
        r = np.maximum(r[:-1], r[1:])
        groups = []
        for j in range(have, k):
            a, b = j * self.h, (j + 1) * self.h
            if j in busy:
                groups.append(self._pieces(a, b))
            else:
                n = max(1, math.ceil(r[j - have] * self.h / MAX_SWEEP))
                if n == 1:
                    groups.append([(a, b)])
                else:
                    xs = np.linspace(a, b, n + 1)
                    groups.append(list(zip(xs[:-1], xs[1:], strict=True)))
        cells = self._integrate(groups)
        self.cum = np.vstack((self.cum, self.cum[-1] + np.cumsum(cells, axis=0)))

    def value(self, t: float) -> np.ndarray:
        """Integral from 0 to t of every component, shape (m,)."""
        if t <= 0:
            return np.zeros(self.m)
        k = int(t // self.h)
        self._ensure(k)
        t0 = k * self.h
        if t == t0:
            return self.cum[k].copy()
        return self.cum[k] + self._integrate([self._pieces(t0, t)])[0]

    def invalidate_after(self, tc: float) -> None:
        keep = int(max(tc, 0.0) // self.h) + 1
        if self.cum.shape[0] > keep:
            self.cum = self.cum[:keep]
