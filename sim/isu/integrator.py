"""Running integrals of the ISU's input rates: exact to quadrature precision, O(1) per query.

Time is cut into fixed cells of ``h`` seconds, each split into pieces at table segment
starts and subdivided when the table turns fast. On each piece the integrand is sampled at
the 8 Gauss-Legendre nodes once; its Legendre interpolant gives both the piece integral
(identical to Gauss-Legendre quadrature) and, analytically, the integral up to any time
inside the piece. A query therefore evaluates a polynomial, never the physics again.
Because cells are fixed, results do not depend on the order of queries. A world change at
tc (a table command) drops the cells from the one holding tc on; they are recomputed with
the new plan when needed.

Components come in two kinds: ``m_int`` integrated rates, and ``m_val`` smooth values that
are only interpolated (the gyro's w.O for its J term). A third, closed-form part handles
the floor vibration: per piece, a matrix (m_int, 3) maps the change of a basis function
(the floor velocity) to increments of the integrated components. ``integrand(nodes, mids)``
returns the node values (N, m_int + m_val) and the matrices at the piece middles.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.polynomial import legendre as leg

ORDER = 8
GL_X, GL_W = leg.leggauss(ORDER)
MAX_SWEEP = math.pi / 2  # rad of table travel per piece
# Cells a batch computes ahead of the one asked for while the table holds (no segment starts
# and one piece per cell): a batch costs about 1 ms whatever its length and a still cell
# about 30 us more, so a gate of up to half an hour costs one batch, like a 1-s gate
# (issue 17), and a static stream asks for one batch per half hour, not per cell.
LOOKAHEAD = 32
# Legendre coefficients from node values: c_n = (2n+1)/2 sum_i w_i P_n(x_i) f_i
_P_NODES = leg.legvander(GL_X, ORDER - 1)  # (8 nodes, 8 degrees)
TO_COEF = (_P_NODES * GL_W[:, None]).T * ((2 * np.arange(ORDER) + 1) / 2.0)[:, None]
# Antiderivative from x = -1, as a linear map on coefficients (8 -> 9)
ANTI = np.stack([leg.legint(np.eye(ORDER)[n], lbnd=-1) for n in range(ORDER)], axis=1)


def _legendre_values(x: float, n: int) -> np.ndarray:
    """P_0(x) .. P_{n-1}(x) by recurrence."""
    p = np.empty(n)
    p[0] = 1.0
    if n > 1:
        p[1] = x
    for k in range(2, n):
        p[k] = ((2 * k - 1) * x * p[k - 1] - (k - 1) * p[k - 2]) / k
    return p


def _legendre_table(x: np.ndarray, n: int) -> np.ndarray:
    """P_0(x) .. P_{n-1}(x) by recurrence at each of the points x, shape (N, n)."""
    p = np.empty((x.size, n))
    p[:, 0] = 1.0
    if n > 1:
        p[:, 1] = x
    for k in range(2, n):
        p[:, k] = ((2 * k - 1) * x * p[:, k - 1] - (k - 1) * p[:, k - 2]) / k
    return p


class CellIntegral:
    def __init__(
        self,
        m_int: int,
        m_val: int,
        h: float,
        integrand: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
        increment_basis: Callable[[float | np.ndarray], np.ndarray],
        breakpoints: Callable[[float, float], list[float]],
        abs_rate: Callable[[np.ndarray], np.ndarray],
        increment_basis_each: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> None:
        self.m_int, self.m_val, self.h = m_int, m_val, h
        self._integrand = integrand
        self._inc_basis = increment_basis
        # the basis at many times, each with the bits increment_basis gives it alone
        self._inc_each = increment_basis_each or (
            lambda t: np.array([increment_basis(np.array([x]))[0] for x in t]).reshape(-1, 3))
        self._breakpoints = breakpoints
        self._abs_rate = abs_rate
        self._cells = 0  # cells [0, _cells) are held
        self._a = np.zeros(0)  # piece starts
        self._b = np.zeros(0)
        self._cum = np.zeros((0, m_int))  # integral from 0 to each piece start
        self._anti = np.zeros((0, ORDER + 1, m_int))
        self._coef = np.zeros((0, ORDER, m_val))
        self._inc = np.zeros((0, m_int, 3))
        self._basis_a = np.zeros((0, 3))
        self._end = np.zeros(m_int)  # integral from 0 to the end of the last piece held

    # ----- building pieces -----
    def _split(self, a: float, b: float, rate: float | None) -> list[tuple[float, float]]:
        """Pieces of [a, b]: cut at segment starts, then so the table turns <= MAX_SWEEP each."""
        if rate is None:
            edges = np.array([a, *self._breakpoints(a, b), b])
            x, y = edges[:-1], edges[1:]
            # rates are linear within a segment (or a decaying settle): the ends bound them
            r = np.maximum(self._abs_rate(x), self._abs_rate(np.maximum(x, y - 1e-9)))
            out: list[tuple[float, float]] = []
            for xi, yi, ri in zip(x, y, r, strict=True):
                if yi > xi:
                    out.extend(self._split(float(xi), float(yi), float(ri)))
            return out
        n = max(1, math.ceil(rate * (b - a) / MAX_SWEEP))
        if n == 1:
            return [(a, b)]
        xs = np.linspace(a, b, n + 1)
        return list(zip(xs[:-1], xs[1:], strict=True))

    def _ensure_cells(self, k: int) -> None:
        """Hold cells [0, k)."""
        if k <= self._cells:
            return
        j0 = self._cells
        k = self._still_until(k)
        busy = {int(x // self.h) for x in self._breakpoints(j0 * self.h, k * self.h)}
        edges = np.arange(j0, k + 1) * self.h
        r = self._abs_rate(edges)
        r = np.maximum(r[:-1], r[1:])
        pieces: list[tuple[float, float]] = []
        for j in range(j0, k):
            lo, hi = j * self.h, (j + 1) * self.h
            pieces.extend(self._split(lo, hi, None if j in busy else float(r[j - j0])))
        ab = np.array(pieces)
        a, b = ab[:, 0], ab[:, 1]
        half = 0.5 * (b - a)
        mid = 0.5 * (a + b)
        nodes = (mid[:, None] + half[:, None] * GL_X[None, :]).ravel()
        # values at the nodes, and the vibration matrices at the piece middles, in one call
        vals, inc = self._integrand(nodes, mid)
        vals = vals.reshape(len(pieces), ORDER, -1)
        f_int, f_val = vals[:, :, : self.m_int], vals[:, :, self.m_int :]
        coef_int = np.einsum("nk,pkm->pnm", TO_COEF, f_int)
        anti = np.einsum("jn,pnm->pjm", ANTI, coef_int) * half[:, None, None]
        coef_val = np.einsum("nk,pkm->pnm", TO_COEF, f_val)
        # pieces are contiguous: one evaluation of the basis at every edge serves both ends
        edges = self._inc_basis(np.concatenate((a, b[-1:])))  # (P + 1, 3)
        basis_a, basis_b = edges[:-1], edges[1:]
        # piece integral: antiderivative at x = 1 is sum of its coefficients (P_n(1) = 1)
        total = anti.sum(axis=1) + np.einsum("pmi,pi->pm", inc, basis_b - basis_a)
        start = self._end if self._a.size else np.zeros(self.m_int)
        cum = start + np.concatenate((np.zeros((1, self.m_int)), np.cumsum(total, axis=0)[:-1]))
        self._a = np.concatenate((self._a, a))
        self._b = np.concatenate((self._b, b))
        self._cum = np.concatenate((self._cum, cum))
        self._anti = np.concatenate((self._anti, anti))
        self._coef = np.concatenate((self._coef, coef_val))
        self._inc = np.concatenate((self._inc, inc))
        self._basis_a = np.concatenate((self._basis_a, basis_a))
        self._end = cum[-1] + total[-1]  # integral from 0 to the end of the last piece
        self._cells = k

    def _still_until(self, k: int) -> int:
        """``k``, or ``k + LOOKAHEAD`` when the table holds over those cells: no segment
        starts in them and its rate leaves one piece per cell."""
        t0, t1 = k * self.h, (k + LOOKAHEAD) * self.h
        if self._breakpoints(t0, t1):
            return k
        if float(np.max(self._abs_rate(np.array([t0, t1])))) * self.h > MAX_SWEEP:
            return k
        return k + LOOKAHEAD

    # ----- queries -----
    def _piece(self, t: float) -> int:
        self._ensure_cells(int(t // self.h) + 1)
        return int(np.searchsorted(self._a, t, side="right")) - 1

    def value(self, t: float) -> np.ndarray:
        """Integral from 0 to t of the integrated components, shape (m_int,)."""
        if t <= 0:
            return np.zeros(self.m_int)
        p = self._piece(t)
        a, b = self._a[p], self._b[p]
        x = (2.0 * t - a - b) / (b - a)
        part = _legendre_values(x, ORDER + 1) @ self._anti[p]
        vib = self._inc[p] @ (self._inc_basis(np.array([t]))[0] - self._basis_a[p])
        return self._cum[p] + part + vib

    def interpolated(self, t: float) -> np.ndarray:
        """The value components at t, shape (m_val,)."""
        p = self._piece(max(t, 0.0))
        a, b = self._a[p], self._b[p]
        x = (2.0 * t - a - b) / (b - a)
        return _legendre_values(x, ORDER) @ self._coef[p]

    # The same queries at many times in one evaluation (the IEU's blocks of samples). Each
    # time's products are the scalar query's, made as a stack of the same small matrix
    # products (numpy's matmul runs one per stacked item): a time's value has the bits of
    # :meth:`value` whether it is asked for alone or in a block.
    def _pieces(self, t: np.ndarray) -> np.ndarray:
        self._ensure_cells(int(float(t.max()) // self.h) + 1)
        return np.searchsorted(self._a, t, side="right") - 1

    def values(self, t: np.ndarray) -> np.ndarray:
        """:meth:`value` at each of the times t, shape (N, m_int)."""
        t = np.asarray(t, dtype=float)
        pos = np.maximum(t, 0.0)
        p = self._pieces(pos)
        a, b = self._a[p], self._b[p]
        x = (2.0 * pos - a - b) / (b - a)
        part = np.matmul(_legendre_table(x, ORDER + 1)[:, None, :], self._anti[p])[:, 0, :]
        d = self._inc_each(pos) - self._basis_a[p]
        vib = np.matmul(self._inc[p], d[:, :, None])[:, :, 0]
        out = self._cum[p] + part + vib
        out[t <= 0] = 0.0
        return out

    def interpolations(self, t: np.ndarray) -> np.ndarray:
        """:meth:`interpolated` at each of the times t, shape (N, m_val)."""
        t = np.asarray(t, dtype=float)
        p = self._pieces(np.maximum(t, 0.0))
        a, b = self._a[p], self._b[p]
        x = (2.0 * t - a - b) / (b - a)
        return np.matmul(_legendre_table(x, ORDER)[:, None, :], self._coef[p])[:, 0, :]

    def invalidate_after(self, tc: float) -> None:
        k = int(max(tc, 0.0) // self.h)
        if self._cells <= k:
            return
        keep = int(np.searchsorted(self._a, k * self.h, side="left"))
        self._a, self._b = self._a[:keep], self._b[:keep]
        self._cum, self._anti = self._cum[:keep], self._anti[:keep]
        self._coef, self._inc = self._coef[:keep], self._inc[:keep]
        self._basis_a = self._basis_a[:keep]
        self._cells = k
        if keep:
            p = keep - 1  # the end of the last kept piece, for the next batch's start
            vb = self._inc_basis(self._b[p : p + 1])[0]
            self._end = self._cum[p] + self._anti[p].sum(axis=0) + self._inc[p] @ (
                vb - self._basis_a[p]
            )
