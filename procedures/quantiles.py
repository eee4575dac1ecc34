"""Student t and F quantiles for the CIGTF significance tests (report 001 section 5.4),
from the regularized incomplete beta function in the standard library's arithmetic.

scipy.special has them (stdtrit, fdtri), but importing it costs a gyrocompassing test about
a fifth of its whole run; tests/test_gyrocompass_analysis.py holds these to scipy's values.
"""

from __future__ import annotations

import math

TINY = 1e-300


def _beta_fraction(a: float, b: float, x: float) -> float:
    """The continued fraction of I_x(a, b) (modified Lentz), good for x < (a + 1)/(a + b + 2)."""
    c, d = 1.0, 1.0 - (a + b) * x / (a + 1.0)
    d = 1.0 / (d if abs(d) > TINY else TINY)
    h = d
    for m in range(1, 10_000):
        m2 = 2 * m
        for num in (m * (b - m) * x / ((a + m2 - 1.0) * (a + m2)),
                    -(a + m) * (a + b + m) * x / ((a + m2) * (a + m2 + 1.0))):
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > TINY else TINY)
            c = 1.0 + num / c
            c = c if abs(c) > TINY else TINY
            h *= d * c
        if abs(d * c - 1.0) < 1e-16:
            break
    return h


def _stirling_tail(y: float) -> float:
    """lgamma(y) less its Stirling leading terms (y >= 10: five terms give 1e-16)."""
    r = 1.0 / (y * y)
    return (1.0 / 12.0 - r * (1.0 / 360.0 - r * (1.0 / 1260.0 - r * (1.0 / 1680.0
            - r / 1188.0)))) / y


def _lgamma_ratio(x: float, h: float) -> float:
    """lgamma(x + h) - lgamma(x), h > 0: for large x without the cancellation of two
    lgamma values of 1e6 (which leaves 1e-9 of the t point at a million dof)."""
    if x < 10.0:
        return math.lgamma(x + h) - math.lgamma(x)
    return ((x - 0.5) * math.log1p(h / x) + h * math.log(x + h) - h
            + _stirling_tail(x + h) - _stirling_tail(x))


def betainc(a: float, b: float, x: float) -> float:
    """Regularized incomplete beta I_x(a, b) for a, b > 0 and 0 <= x <= 1."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    big, small = max(a, b), min(a, b)
    front = math.exp(_lgamma_ratio(big, small) - math.lgamma(small)
                     + a * math.log(x) + b * math.log1p(-x))
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _beta_fraction(a, b, x) / a
    return 1.0 - front * _beta_fraction(b, a, 1.0 - x) / b


def _solve_beta(a: float, b: float, p: float) -> float:
    """x in (0, 1) with I_x(a, b) = p, by bisection to the last bits (I is increasing)."""
    lo, hi = 0.0, 1.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if betainc(a, b, mid) < p:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def f_quantile(p: float, dfn: float, dfd: float) -> float:
    """The F(dfn, dfd) point below which a fraction p lies (scipy's fdtri(dfn, dfd, p))."""
    a, b = 0.5 * dfn, 0.5 * dfd
    y = _solve_beta(a, b, p)  # y = dfn F / (dfn F + dfd)
    if y <= 0.5:
        return dfd * y / (dfn * (1.0 - y))
    z = _solve_beta(b, a, 1.0 - p)  # 1 - y, solved for itself: 1 - y would lose its bits
    return dfd * (1.0 - z) / (dfn * z)


def t_quantile(p: float, dof: float) -> float:
    """Student's t point below which a fraction p > 1/2 lies (scipy's stdtrit(dof, p))."""
    if p <= 0.5:
        return -t_quantile(1.0 - p, dof) if p < 0.5 else 0.0
    y = _solve_beta(0.5 * dof, 0.5, 2.0 * (1.0 - p))  # y = dof / (dof + t^2), I_y = 2(1 - p)
    return math.sqrt(dof * (1.0 - y) / y)
