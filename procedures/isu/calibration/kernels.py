"""Covariances of linear functionals of stationary processes (point values and gate means).

A measurement error that a slow process x(t) causes is a linear functional of x: a gyro
sees the tilt change over its gate, (x(t1) - x(t0)) / T; a level-corrected accelerometer
sees the gate mean minus the value at the bubble reading. A ``Functional`` is a sum of
atoms (weight, a, b): a point value x(a) when a == b, else the mean of x over [a, b].

``exp_gram``: covariance for K(tau) = exp(-|tau|/tau_c) in closed form (second
antiderivative Phi(x) = tau_c^2 (exp(-|x|/tau_c) - 1 + |x|/tau_c), written with expm1).
``cosine_gram``: covariance for K(tau) = integral of w(f) cos(2 pi f tau) df given as
quadrature nodes (f, w): each functional's Fourier transform is exact (a gate mean of
exp(2 pi i f t) is exp(2 pi i f c) sinc(f T)), so the diurnal term (one node) and the
wobble (a band of nodes) are exact up to the band quadrature.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Functional:
    atoms: tuple[tuple[float, float, float], ...]  # (weight, a, b)

    @staticmethod
    def point(t: float, w: float = 1.0) -> Functional:
        return Functional(((w, t, t),))

    @staticmethod
    def mean(a: float, b: float, w: float = 1.0) -> Functional:
        return Functional(((w, a, b),))

    def __add__(self, other: Functional) -> Functional:
        return Functional(self.atoms + other.atoms)

    def scaled(self, s: float) -> Functional:
        return Functional(tuple((w * s, a, b) for w, a, b in self.atoms))


ZERO = Functional(())


def _flatten(fs: Sequence[Functional]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    owner, w, a, b = [], [], [], []
    for i, f in enumerate(fs):
        for wi, ai, bi in f.atoms:
            owner.append(i)
            w.append(wi)
            a.append(ai)
            b.append(bi)
    return (np.array(owner, dtype=int), np.array(w), np.array(a), np.array(b))


def _phi1(x: np.ndarray, tc: float) -> np.ndarray:
    """First antiderivative of exp(-|x|/tc), zero at 0."""
    return np.sign(x) * tc * -np.expm1(-np.abs(x) / tc)


def _phi2(x: np.ndarray, tc: float) -> np.ndarray:
    """Second antiderivative of exp(-|x|/tc), up to a constant that cancels."""
    ax = np.abs(x)
    return tc * tc * (np.expm1(-ax / tc) + ax / tc)


def exp_gram(fs: Sequence[Functional], tc: float) -> np.ndarray:
    """Matrix of E[F_i x F_j x] for a unit-variance process with covariance exp(-|tau|/tc).

    Written through each functional's coefficients on the distinct times it reads (P for
    its point values, U for its gate means: w / L at a gate's end, -w / L at its start):
    G = P K P' - (P Phi1 U' + its transpose) - U Phi2 U', with K, Phi1 and Phi2 the kernel
    and its antiderivatives over those times. Gates that share ends (a tilt functional's
    consecutive steps) share their evaluations: 17x faster than the kernel per pair of
    atoms on the J experiment's 672 atoms (issue 17); the same matrix within 5e-13."""
    n = len(fs)
    owner, w, a, b = _flatten(fs)
    if owner.size == 0:
        return np.zeros((n, n))
    length = b - a
    pt = length == 0
    tp, at_p = np.unique(a[pt], return_inverse=True)  # the point values' times
    p = np.zeros((n, tp.size))
    np.add.at(p, (owner[pt], at_p), w[pt])
    gate = ~pt
    m = int(gate.sum())
    te, at_e = np.unique(np.concatenate([a[gate], b[gate]]), return_inverse=True)
    c = w[gate] / length[gate]
    u = np.zeros((n, te.size))
    np.add.at(u, (owner[gate], at_e[m:]), c)
    np.add.at(u, (owner[gate], at_e[:m]), -c)
    out: np.ndarray = p @ np.exp(-np.abs(tp[:, None] - tp[None, :]) / tc) @ p.T
    if m:
        cross = p @ _phi1(tp[:, None] - te[None, :], tc) @ u.T  # point values, gate means
        out -= cross + cross.T
        out -= u @ _phi2(te[:, None] - te[None, :], tc) @ u.T
    return out


def fourier(fs: Sequence[Functional], freqs: np.ndarray) -> np.ndarray:
    """F_i applied to exp(2 pi i f t), shape (len(fs), len(freqs))."""
    owner, w, a, b = _flatten(fs)
    out = np.zeros((len(fs), freqs.size), dtype=complex)
    if owner.size == 0:
        return out
    c = 0.5 * (a + b)
    ph = np.exp(2j * math.pi * np.outer(c, freqs)) * np.sinc(np.outer(b - a, freqs))
    _add_rows(out, owner, w[:, None] * ph)
    return out


def _add_rows(out: np.ndarray, owner: np.ndarray, rows: np.ndarray) -> None:
    """``np.add.at(out, owner, rows)`` for ``owner`` in increasing order (``_flatten``'s):
    each functional's atoms added one after another from zero, as add.at adds them (the
    same bits), the k-th atoms of every functional at once: 3x faster on the day's tilt
    functionals (issue 17; np.add.reduceat sums in another order)."""
    first = np.flatnonzero(np.r_[True, owner[1:] != owner[:-1]])
    counts = np.diff(np.r_[first, owner.size])
    rank = np.arange(owner.size) - np.repeat(first, counts)
    for k in range(int(counts.max())):
        kth = rank == k
        out[owner[kth]] += rows[kth]


def cosine_gram(fs: Sequence[Functional], freqs: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """E[F_i x F_j x] for covariance sum_k weights_k cos(2 pi freqs_k tau)."""
    lam = fourier(fs, np.asarray(freqs, dtype=float))
    return np.real((lam * np.asarray(weights)[None, :]) @ lam.conj().T)


_GAUSS8 = np.polynomial.legendre.leggauss(8)  # the panel rule's nodes, computed once


def band_nodes(f_lo: float, f_hi: float, span_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre nodes and weights for a uniform density over [f_lo, f_hi].

    Composite 8-point rule with at most half an oscillation of the integrand per panel for
    time separations up to ``span_s``; the weights sum to 1.
    """
    panels = int(min(5000, 4 + math.ceil(2.0 * (f_hi - f_lo) * max(span_s, 1.0))))
    x, wt = _GAUSS8
    edges = np.linspace(f_lo, f_hi, panels + 1)
    mid, half = 0.5 * (edges[1:] + edges[:-1]), 0.5 * np.diff(edges)
    f = (mid[:, None] + half[:, None] * x[None, :]).ravel()
    w = (half[:, None] * wt[None, :]).ravel() / (f_hi - f_lo)
    return f, w
