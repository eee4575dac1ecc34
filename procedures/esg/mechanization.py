"""Nominal mechanization of the great-circle pattern (report 004, eqs. 1-10).

Conventions (docs/esg.md): the two trailing edges are the minor circles

    b sin(th) sin(ph) + c cos(th) = d_k,      normal (0, b, c), b = sin i, c = cos i,

line 1 near ph = 0 with d1 = d0 - w/2, line 2 near ph = pi with d2 = d0 + w/2. A pickoff
at colatitude th sees line 1's trailing edge at ph1 = asin(s1) and line 2's at
ph2 = pi - asin(s2), with s_k = (d_k - c cos th) / (b sin th) (eqs. 5, 6). The count
ratio is CR = mu / (2 pi), mu = ph2 - ph1 (eq. 3), so with the "primary values"
ph2' = asin(s2) one has ph1 + ph2' = pi - mu (eq. 4).

Derivation of the nominal equation. Adding the two edge equations,

    s1 + s2 = (d1 + d2 - 2 c cos th) / (b sin th)
            = sin ph1 + sin ph2' = 2 sin((ph1 + ph2')/2) cos((ph1 - ph2')/2)
            = 2 cos(mu/2) F,        F = cos((ph1 - ph2')/2)                  (eq. 7)

With X = cos(mu/2) = sin((pi - mu)/2) and dbar = (d1 + d2)/2 this is exactly
``b X F sin th + c cos th = dbar``. The report drops F (nearly 1 because ph1 ~ ph2'):

    b X sin th + c cos th = dbar                                           (eq. 8)

F = 1 exactly when d1 = d2 (then ph1 = ph2'), whatever their common value. With
d1 - d2 = -w, to second order 1 - F = w^2 / (8 (1 - sin ph1 sin ph2') (b sin th)^2),
which is the report's expression; for the contract's pattern (i = 56 deg, w = 0.060)
F >= 0.997 over 43..137 deg (the report quotes 0.98 < F < 1 as a loose bound). The
colatitude error of dropping F is, to first order, th_n - th = -(1 - F) sin(2 th) / 2
(at dbar = 0): about -0.085 deg at th = 43 deg, zero at the equator, and of opposite sign
in the other hemisphere. The calibration polynomial (eq. 11) absorbs it.

Solving eq. 8 for u = cos th: put A = b X, D = c^2 + A^2; squaring A sin th = dbar - c u
gives D u^2 - 2 c dbar u + dbar^2 - A^2 = 0, roots u = (c dbar -+ |A| sqrt(D - dbar^2))/D.
The true root is the one with sign(dbar - c u) = sign(A) (sin th >= 0); it is

    cos th_n = -(A / sqrt(D)) sqrt(1 - dbar^2 / D) + c dbar / D             (eq. 10)

which reduces to eq. 9, cos th = -b X / sqrt(c^2 + b^2 X^2), at dbar = 0. (The OCR of
eq. 10 shows ``1 + d^2/...`` under the root; the derivation gives a minus sign.)
Sign check: th < 90 deg -> cos th > 0 -> X < 0 -> mu > pi -> CR > 0.5, as the contract
and Table B-1 (50 deg <-> 0.70) have it.

Colatitudes at this module's interface are in degrees (the dividing-head unit); b, c,
dbar are dimensionless (units of the rotor radius).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from procedures.esg.cosine import CosineParams, cosine_cos, cosine_count_ratio, fit_cosine

__all__ = [
    "Mechanization",
    "NominalParams",
    "half_phase",
    "nominal_cos",
    "nominal_colatitude",
    "nominal_count_ratio",
    "exact_count_ratio",
    "nominal_factor",
    "pickoff_gram",
    "equal_ratio_colatitude",
    "fit_nominal",
    "fit_mechanization",
]


@dataclass(frozen=True)
class NominalParams:
    """Great-circle mechanization parameters: edge-plane normal (0, b, c), mean offset dbar."""

    b: float
    c: float
    dbar: float

    @property
    def inclination_deg(self) -> float:
        """Inclination i of the pattern at the equator (b = sin i, c = cos i)."""
        return math.degrees(math.atan2(self.b, self.c))


# the great circle's (this module) or the cosine pattern's (procedures/esg/cosine.py)
Mechanization = NominalParams | CosineParams


def half_phase(cr: ArrayLike) -> np.ndarray:
    """X = cos(mu / 2) = sin((pi - mu) / 2), mu = 2 pi CR (eqs. 3, 4)."""
    return np.cos(np.pi * np.asarray(cr, dtype=float))


def nominal_cos(cr: ArrayLike, params: Mechanization) -> np.ndarray:
    """cos(th_n) from count ratios by the closed-form root of eq. 8 (eq. 10); vectorised.
    A cosine pattern's by its own mechanization (procedures/esg/cosine.py)."""
    if isinstance(params, CosineParams):
        return cosine_cos(cr, params)
    b, c, d = params.b, params.c, params.dbar
    a = b * half_phase(cr)
    den = c * c + a * a
    root = np.sqrt(np.clip(den - d * d, 0.0, None))
    return (c * d - a * root) / den


def nominal_colatitude(cr: ArrayLike, params: Mechanization) -> np.ndarray:
    """Nominal colatitude th_n (deg) for count ratios (eq. 10); vectorised."""
    return np.degrees(np.arccos(np.clip(nominal_cos(cr, params), -1.0, 1.0)))


def nominal_count_ratio(theta_deg: ArrayLike, params: Mechanization) -> np.ndarray:
    """Inverse of eq. 8: the count ratio the nominal mechanization assigns to a colatitude."""
    if isinstance(params, CosineParams):
        return cosine_count_ratio(theta_deg, params)
    th = np.radians(np.asarray(theta_deg, dtype=float))
    x = (params.dbar - params.c * np.cos(th)) / (params.b * np.sin(th))
    return np.arccos(np.clip(x, -1.0, 1.0)) / np.pi


def exact_count_ratio(theta_deg: ArrayLike, b: float, c: float, d1: float, d2: float) -> np.ndarray:
    """Count ratio from the exact edge geometry (eqs. 1-6): (ph2 - ph1) / (2 pi)."""
    th = np.radians(np.asarray(theta_deg, dtype=float))
    bs = b * np.sin(th)
    ph1 = np.arcsin(np.clip((d1 - c * np.cos(th)) / bs, -1.0, 1.0))
    ph2 = np.pi - np.arcsin(np.clip((d2 - c * np.cos(th)) / bs, -1.0, 1.0))
    return (ph2 - ph1) / (2.0 * np.pi)


def nominal_factor(theta_deg: ArrayLike, b: float, c: float, d1: float, d2: float) -> np.ndarray:
    """F = cos((ph1 - ph2') / 2), the factor eq. 8 drops (eq. 7)."""
    th = np.radians(np.asarray(theta_deg, dtype=float))
    bs = b * np.sin(th)
    ph1 = np.arcsin(np.clip((d1 - c * np.cos(th)) / bs, -1.0, 1.0))
    ph2p = np.arcsin(np.clip((d2 - c * np.cos(th)) / bs, -1.0, 1.0))
    return np.cos(0.5 * (ph1 - ph2p))


def pickoff_gram(mirror_angle_deg: float = 90.0) -> np.ndarray:
    """Gram matrix of pickoffs p1, p2 at the measured mirror angle, p3 normal to their plane."""
    ca = math.cos(math.radians(mirror_angle_deg))
    return np.array([[1.0, ca, 0.0], [ca, 1.0, 0.0], [0.0, 0.0, 1.0]])


def equal_ratio_colatitude(pickoff_gram: np.ndarray) -> float:
    """Colatitude (deg) at which all three pickoffs make the same angle with the spin axis.

    With P the matrix of pickoff rows, P s = k (1, 1, 1) gives s = k P^-1 1 and |s| = 1
    gives k^2 = 1 / (1' (P P')^-1 1) = 1 / (1' G^-1 1). The two solutions +-s are the
    points th* and 180 - th*. Orthogonal pickoffs: acos(1/sqrt 3) = 54.73561 deg; mirrors
    89 deg 56 min 5 sec apart with p3 perpendicular: 54.72023 deg.
    """
    g = np.asarray(pickoff_gram, dtype=float)
    ones = np.ones(g.shape[0])
    q = float(ones @ np.linalg.solve(g, ones))
    return math.degrees(math.acos(1.0 / math.sqrt(q)))


def fit_nominal(cr_a: float, cr_b: float, theta_star: float) -> NominalParams:
    """b, c, dbar from the two equal-ratio points (report, "Data Reduction Technique").

    ``cr_a`` is the count ratio at colatitude ``theta_star`` (deg, < 90: CR > 0.5) and
    ``cr_b`` at 180 - theta_star. Eq. 8 at the two points,

        b X_a sin th* + c cos th* = dbar,      b X_b sin th* - c cos th* = dbar,

    subtracted give b (X_b - X_a) sin th* = 2 c cos th*, so with b^2 + c^2 = 1 the
    direction (b, c) is (2 cos th*, (X_b - X_a) sin th*) normalised (b, c > 0); added they
    give dbar = b (X_a + X_b) sin th* / 2. Exact, no iteration.
    """
    th = math.radians(theta_star)
    xa, xb = float(half_phase(cr_a)), float(half_phase(cr_b))
    vb, vc = 2.0 * math.cos(th), (xb - xa) * math.sin(th)
    norm = math.hypot(vb, vc)
    if norm == 0.0 or vb / norm <= 0.0 or vc / norm <= 0.0:
        raise ValueError(f"count ratios {cr_a}, {cr_b} at {theta_star} deg give no b, c > 0 "
                         "(cr_a belongs to the colatitude below 90 deg and must exceed cr_b)")
    b, c = vb / norm, vc / norm
    return NominalParams(b=b, c=c, dbar=0.5 * b * (xa + xb) * math.sin(th))


def fit_mechanization(kind: str, cr_a: float, cr_b: float, theta_star: float
                      ) -> Mechanization:
    """The nominal mechanization of a ``great_circle`` or ``cosine`` pattern from the two
    equal-ratio points."""
    if kind == "cosine":
        return fit_cosine(cr_a, cr_b, theta_star)
    if kind != "great_circle":
        raise ValueError(f"pattern kind must be great_circle or cosine, not {kind!r}")
    return fit_nominal(cr_a, cr_b, theta_star)
