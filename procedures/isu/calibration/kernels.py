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


def _flatten(fs: list[Functional]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
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


def exp_gram(fs: list[Functional], tc: float) -> np.ndarray:
    """Matrix of E[F_i x F_j x] for a unit-variance process with covariance exp(-|tau|/tc)."""
    n = len(fs)
    owner, w, a, b = _flatten(fs)
    out = np.zeros((n, n))
    if owner.size == 0:
        return out
    A1, A2 = np.meshgrid(a, a, indexing="ij")
    B1, B2 = np.meshgrid(b, b, indexing="ij")
    L1, L2 = B1 - A1, B2 - A2
    p1, p2 = L1 == 0, L2 == 0
    val = np.empty_like(A1)
    # point - point
    m = p1 & p2
    val[m] = np.exp(-np.abs(A1[m] - A2[m]) / tc)
    # point - interval (either way round)
    m = p1 & ~p2
    val[m] = (_phi1(A1[m] - A2[m], tc) - _phi1(A1[m] - B2[m], tc)) / L2[m]
    m = ~p1 & p2
    val[m] = (_phi1(A2[m] - A1[m], tc) - _phi1(A2[m] - B1[m], tc)) / L1[m]
    # interval - interval
    m = ~p1 & ~p2
    val[m] = (
        _phi2(B1[m] - A2[m], tc)
        - _phi2(A1[m] - A2[m], tc)
        - _phi2(B1[m] - B2[m], tc)
        + _phi2(A1[m] - B2[m], tc)
    ) / (L1[m] * L2[m])
    val *= np.outer(w, w)
    np.add.at(out, (owner[:, None], owner[None, :]), val)
    return out


def fourier(fs: list[Functional], freqs: np.ndarray) -> np.ndarray:
    """F_i applied to exp(2 pi i f t), shape (len(fs), len(freqs))."""
    owner, w, a, b = _flatten(fs)
    out = np.zeros((len(fs), freqs.size), dtype=complex)
    if owner.size == 0:
        return out
    c = 0.5 * (a + b)
    ph = np.exp(2j * math.pi * np.outer(c, freqs)) * np.sinc(np.outer(b - a, freqs))
    np.add.at(out, owner, w[:, None] * ph)
    return out


def cosine_gram(fs: list[Functional], freqs: np.ndarray, weights: np.ndarray) -> np.ndarray:
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
