"""Nominal mechanization of the cosine pattern (report 004, "Pattern Analysis": the
alternative to the great circle, smallest error amplification, "the most difficult to
apply"; docs/esg-options.md).

The report gives no mechanization equation for the cosine line (it says the direction
cosines come out "only slightly more complicated" from a great circle than from a cosine
line). Ours, from the drawing: a cosine line is the curve K phi = cos(theta) near phi = 0
and K (pi - phi) = cos(theta) near phi = pi; an edge is the curve at perpendicular
distance D from it, K phi = cos(theta) + D g(theta) with g = sqrt(sin^2 + K^2 / sin^2)
the surface gradient of K phi - cos(theta). With line 1's trailing edge at d0 + w/2 and
line 2's at d0 - w/2 (one pass lays both lines, as for the great circle) the count ratio
CR = (phi2 - phi1) / (2 pi) is

    CR = 1/2 - (cos(theta) + d0 g(theta)) / (pi K)

so cos(theta) is linear in the count ratio but for the offset term (d0 ~ 1e-3 of the
radius). The count ratio falls through the equator with the colatitude, the other way from
the great circle's. The two equal-ratio points (theta*, 180 - theta*: g is the same) give
K from their difference and d0 from their sum, exactly, as b, c, dbar come from them for
the great circle. Colatitudes at this interface are in degrees.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike


@dataclass(frozen=True)
class CosineParams:
    """Cosine-pattern mechanization: the line's K and the pass's offset d0 (radii)."""

    k: float
    d0: float


def _g(cos_theta: np.ndarray, k: float) -> np.ndarray:
    s2 = np.clip(1.0 - cos_theta * cos_theta, 1e-12, None)
    return np.sqrt(s2 + k * k / s2)


def cosine_cos(cr: ArrayLike, p: CosineParams) -> np.ndarray:
    """cos(theta_n) from count ratios (the equation above, solved by fixed point: the
    offset term changes cos(theta) by about 1e-3, and its slope in cos(theta) is below
    0.01 over the pattern, so four steps leave nothing)."""
    u0 = math.pi * p.k * (0.5 - np.asarray(cr, dtype=float))
    u = u0.copy()
    for _ in range(4):
        u = u0 - p.d0 * _g(np.clip(u, -0.999, 0.999), p.k)
    return u


def cosine_count_ratio(theta_deg: ArrayLike, p: CosineParams) -> np.ndarray:
    """The count ratio the cosine mechanization gives a colatitude."""
    c = np.cos(np.radians(np.asarray(theta_deg, dtype=float)))
    return 0.5 - (c + p.d0 * _g(c, p.k)) / (math.pi * p.k)


def fit_cosine(cr_a: float, cr_b: float, theta_star: float) -> CosineParams:
    """K and d0 from the two equal-ratio points: ``cr_a`` at ``theta_star`` (deg, below
    90) and ``cr_b`` at 180 - theta_star. CR_b - CR_a = 2 cos(theta*) / (pi K);
    CR_a + CR_b = 1 - 2 d0 g(theta*) / (pi K)."""
    c = math.cos(math.radians(theta_star))
    if cr_b <= cr_a:
        raise ValueError(f"count ratios {cr_a}, {cr_b} at {theta_star} deg give no K > 0 "
                         "(on a cosine pattern cr_a, below 90 deg, is the smaller)")
    k = 2.0 * c / (math.pi * (cr_b - cr_a))
    g = float(_g(np.array(c), k))
    return CosineParams(k=k, d0=(1.0 - cr_a - cr_b) * math.pi * k / (2.0 * g))
