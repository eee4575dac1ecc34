"""Weighted Chebyshev least squares of the pattern deviation (report 004, eqs. 11-12).

The calibration models the deviation of the measured colatitude from the nominal
mechanization as a polynomial in the count ratio y (eq. 11),

    cos th_m - cos th_n(y) = p0 + p1 y + ... + pn y^n,       n = 7 by default,

built on first-kind Chebyshev polynomials T_j(x) of x = (2 y - (lo + hi)) / (hi - lo),
where [lo, hi] is the data's count-ratio range widened by a margin (0.005 count ratio) at
each end. The weight is W(x) = (1 - x^2)^(-1/2) (eq. 12), the Chebyshev weight; the
margin keeps it finite at the outermost samples (without it the end points get infinite
weight). The least-squares solution minimises sum_k W_k (f_k - sum_j a_j T_j(x_k))^2.

The report also tried a "direct" solution that treats the T_j as orthogonal over the
samples, i.e. keeps only the diagonal of the weighted normal matrix:
a_j = sum_k W_k f_k T_j(x_k) / sum_k W_k T_j(x_k)^2. It equals the least-squares solution
only when the weighted normal matrix is diagonal, which the calibration samples (uniform
in colatitude, not in x) do not give; it is kept for information.

The power-series coefficients p0..pn in y follow from numpy.polynomial's conversion.
Residual sign follows Appendix B: error = compensated - measured (degrees).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.polynomial import Chebyshev, Polynomial
from numpy.polynomial import chebyshev as C
from numpy.typing import ArrayLike

from procedures.esg.mechanization import Mechanization, nominal_cos

__all__ = ["ChebyshevFit", "chebyshev_lsq", "fit_deviation", "residuals"]

MARGIN_CR = 0.005


@dataclass(frozen=True)
class ChebyshevFit:
    """A fitted deviation polynomial on the count-ratio interval [lo, hi]."""

    lo: float
    hi: float
    coef: np.ndarray            # Chebyshev coefficients a_0..a_n (least squares)
    coef_direct: np.ndarray     # the same assuming discrete orthogonality
    params: Mechanization | None = None

    @property
    def order(self) -> int:
        return len(self.coef) - 1

    def x(self, cr: ArrayLike) -> np.ndarray:
        """The linear map of count ratio onto [-1, 1] (data range plus margins)."""
        return (2.0 * np.asarray(cr, dtype=float) - (self.lo + self.hi)) / (self.hi - self.lo)

    def weight(self, cr: ArrayLike) -> np.ndarray:
        """Eq. 12 weight (1 - x^2)^(-1/2) at count ratios."""
        x = self.x(cr)
        return 1.0 / np.sqrt(1.0 - x * x)

    def _coef(self, direct: bool) -> np.ndarray:
        return self.coef_direct if direct else self.coef

    def chebyshev(self, direct: bool = False) -> Chebyshev:
        return Chebyshev(self._coef(direct), domain=[self.lo, self.hi])

    def power_coefficients(self, direct: bool = False) -> np.ndarray:
        """p0..pn of eq. 11 (power series in the count ratio y)."""
        p = self.chebyshev(direct).convert(kind=Polynomial).coef
        out = np.zeros(self.order + 1)
        out[: len(p)] = p
        return out

    @property
    def power(self) -> np.ndarray:
        return self.power_coefficients(False)

    def deviation(self, cr: ArrayLike, direct: bool = False) -> np.ndarray:
        """The modelled cos th_m - cos th_n at count ratios."""
        return C.chebval(self.x(cr), self._coef(direct))

    def cos_colatitude(self, cr: ArrayLike, direct: bool = False) -> np.ndarray:
        if self.params is None:
            raise ValueError("this fit has no nominal mechanization attached")
        return nominal_cos(cr, self.params) + self.deviation(cr, direct)

    def colatitude(self, cr: ArrayLike, direct: bool = False) -> np.ndarray:
        """Compensated colatitude (deg) for count ratios."""
        return np.degrees(np.arccos(np.clip(self.cos_colatitude(cr, direct), -1.0, 1.0)))


def chebyshev_lsq(y: ArrayLike, f: ArrayLike, order: int = 7, margin: float = MARGIN_CR
                  ) -> tuple[float, float, np.ndarray, np.ndarray]:
    """(lo, hi, least-squares coefficients, direct coefficients) of f(y), eq. 12 weights."""
    y = np.asarray(y, dtype=float)
    f = np.asarray(f, dtype=float)
    if margin <= 0.0:
        raise ValueError("margin must be positive: the eq. 12 weight is infinite at x = +-1")
    if y.shape != f.shape or y.ndim != 1:
        raise ValueError("y and f must be 1-D arrays of the same length")
    if len(y) < order + 1:
        raise ValueError(f"{len(y)} samples cannot fix {order + 1} coefficients")
    lo, hi = float(y.min()) - margin, float(y.max()) + margin
    x = (2.0 * y - (lo + hi)) / (hi - lo)
    w = 1.0 / np.sqrt(1.0 - x * x)
    t = C.chebvander(x, order)                    # T_j(x_k)
    sw = np.sqrt(w)
    coef, *_ = np.linalg.lstsq(t * sw[:, None], f * sw, rcond=None)
    direct = (w * f) @ t / ((w[:, None] * t * t).sum(axis=0))
    return lo, hi, coef, direct


def fit_deviation(cr: ArrayLike, theta_deg: ArrayLike, params: Mechanization, order: int = 7,
                  margin: float = MARGIN_CR) -> ChebyshevFit:
    """Fit eq. 11 to measured colatitudes (deg) at count ratios, nominal ``params``."""
    cr = np.asarray(cr, dtype=float)
    f = np.cos(np.radians(np.asarray(theta_deg, dtype=float))) - nominal_cos(cr, params)
    lo, hi, coef, direct = chebyshev_lsq(cr, f, order, margin)
    return ChebyshevFit(lo=lo, hi=hi, coef=coef, coef_direct=direct, params=params)


def residuals(fit: ChebyshevFit, cr: ArrayLike, theta_deg: ArrayLike,
              direct: bool = False) -> np.ndarray:
    """Calibration or readout error (deg): compensated minus measured colatitude."""
    return fit.colatitude(cr, direct) - np.asarray(theta_deg, dtype=float)
